"""Results an OpenSim user can load with the same .osim model: a motion and controls.

* ``motion.mot``: the model's own coordinates (its names, signs and units) over time, as
  OpenSim writes motions: ``inDegrees=yes``, rotational coordinates in degrees, translational
  and coupled ones (OpenSim's motion types) in metres and radians as OpenSim expects them. The
  plant's ``pelvis_tx`` is no coordinate of a model whose pelvis is welded and is left out
  (it moves no muscle relative to the pelvis).
* ``controls.sto``: muscle excitations, one column per muscle (OpenSim's controls file).
* ``activations.sto``: muscle activations labelled as OpenSim state variables
  (``/forceset/<muscle>/activation``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trunk_drake.io.storage import write_storage


def source_motion(model, q: np.ndarray) -> dict[str, np.ndarray]:
    """The OpenSim model's coordinates (OpenSim units: degrees for rotational ones) over the rows of q."""
    values = [model.source_coordinates(row) for row in np.atleast_2d(q)]
    out = {}
    for coord in model.spec.coordinates:
        column = np.array([v[coord.name] for v in values])
        out[coord.name] = np.degrees(column) if coord.kind == "rotational" else column
    return out


def write_opensim_results(result, model, out_dir) -> dict[str, Path]:
    """Write motion.mot, controls.sto and activations.sto of a SimulationResult on an OpenSim model."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"motion": out / "motion.mot", "controls": out / "controls.sto", "activations": out / "activations.sto"}
    write_storage(paths["motion"], time=result.time, columns=source_motion(model, result.q), in_degrees=True,
                  name=f"trunk-drake motion of {model.spec.name}")
    write_storage(paths["controls"], time=result.time, in_degrees=False, name="trunk-drake controls",
                  columns={m: result.excitation[:, i] for i, m in enumerate(result.muscles)})
    write_storage(paths["activations"], time=result.time, in_degrees=False, name="trunk-drake activations",
                  columns={f"/forceset/{m}/activation": result.activation[:, i] for i, m in enumerate(result.muscles)})
    return paths
