"""Short-range stiffness (SRS) of active muscle, added to a Hill-type (Thelen) muscle.

For small, quick length changes active muscle is much stiffer than its force-length curve says
(cross-bridges stretch before they detach); Cui et al. (2008) model that stiffness as
proportional to the active force. Here, as in De Groote et al. (2017), the SRS force along
the fiber is

    F_srs = gain * a * f_AL(l_n) * F_max * clip(l_n - l_ref, -max_stretch, max_stretch)

with l_n the normalised fiber length and l_ref a reference that tracks l_n with the time
constant `time_constant` (the stiffness acts on quick deviations and fades on slow ones, so it
changes no equilibrium). Beyond `max_stretch` the cross-bridges have detached: the force stays
at its limit. Constants and their sources: ``models/reference_values.toml`` [muscle.srs].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ShortRangeStiffness:
    """SRS constants: `gain` (F_max per optimal fiber length at a = f_AL = 1), `max_stretch`
    (normalised fiber stretch where the force stops rising), `time_constant` (s) of the reference length."""

    gain: float = 280.0
    max_stretch: float = 5.7e-3
    time_constant: float = 0.05

    def __post_init__(self):
        for name in ("gain", "max_stretch", "time_constant"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"ShortRangeStiffness.{name} must be a finite number > 0, got {value!r}")

    @classmethod
    def from_reference(cls) -> "ShortRangeStiffness":
        """The constants recorded in models/reference_values.toml [muscle.srs]."""
        from trunk_drake.data import load_toml

        srs = load_toml("reference_values.toml")["muscle"]["srs"]
        return cls(gain=srs["gain"]["value"], max_stretch=srs["max_stretch"]["value"],
                   time_constant=srs["time_constant"]["value"])

    def fiber_force(self, activation, active_force_length, max_isometric_force, stretch) -> np.ndarray:
        """SRS force along the fiber (N) for normalised stretch l_n - l_ref."""
        limited = np.clip(stretch, -self.max_stretch, self.max_stretch)
        return self.gain * activation * active_force_length * max_isometric_force * limited

    def path_stiffness(self, activation, active_force_length, max_isometric_force, optimal_fiber_length,
                       cos_pennation) -> np.ndarray:
        """d(tendon force)/d(musculotendon length) of the SRS about l_ref = l_n (N/m), rigid tendon:
        the fiber stretches by cos(phi) per unit of path and its force acts along the tendon with cos(phi)."""
        return self.gain * activation * active_force_length * max_isometric_force / optimal_fiber_length * cos_pennation**2

    def reference_rate(self, normalized_fiber_length, reference) -> np.ndarray:
        """d l_ref / dt (1/s): first-order tracking of the normalised fiber length."""
        return (normalized_fiber_length - reference) / self.time_constant
