"""The passenger as a web page: bones against MuJoCo, wrap arcs, the exported HTML and its playback."""

import base64
import re
import select
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import mujoco
import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.visual.geometry import ARC_POINTS, Drawing, wrap_arcs
from trunk_drake.visual.meshes import bone_meshes
from trunk_drake.visual.page import embedded_player as player
from trunk_drake.visual.page import external_urls, recorded_positions
from trunk_drake.visual.page import scene_commands as scene_messages

DURATION = 1.0


@pytest.fixture(scope="module")
def model():
    return td.load_model("sagittal")


@pytest.fixture(scope="module")
def result(model):
    """1 s without co-activation: the trunk sinks into flexion and the back muscles' stretch reflex fires."""
    return td.simulate(model, duration=DURATION, kp={"sacrospinalis": 1.0, "transversospinalis": 1.0})


@pytest.fixture(scope="module")
def page(model, result, tmp_path_factory):
    path = tmp_path_factory.mktemp("visual") / "animation.html"
    return td.animate(result, path, model)


# ------------------------------------------------------------------------------ geometry

def test_bones_sit_where_mujoco_draws_them(model):
    """Every bone vertex, placed by our plant's body poses, lands where MuJoCo renders MyoTorso's meshes."""
    from trunk_drake.model.myotorso import compile_myotorso

    m = compile_myotorso()
    m.eq_active0[:] = 0
    d = mujoco.MjData(m)
    drawing = Drawing(model)
    q = np.array([0.0, 0.15, -0.1, 0.2, 0.05, -0.12])  # pelvis_tx stays 0: MyoTorso has no such joint
    for c, value in zip(model.coordinate_info[1:], q[1:]):
        d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, c.source_joint)]] = c.sign * value
    mujoco.mj_kinematics(m, d)
    R, p = drawing.poses(q)
    names = model.body_names
    checked = 0
    for body, path in bone_meshes().items():
        ours = _obj_vertices(path) @ R[names.index(body)].T + p[names.index(body)]
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
        theirs = [d.geom_xmat[g].reshape(3, 3) @ m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]].T
                  + d.geom_xpos[g][:, None]
                  for g in range(m.ngeom) if m.geom_bodyid[g] == b and (k := m.geom_dataid[g]) >= 0 and m.geom_group[g] == 0]
        theirs = np.hstack(theirs).T
        np.testing.assert_allclose(ours[:len(theirs)], theirs, atol=2e-5, err_msg=body)  # OBJ keeps 10 um
        checked += len(theirs)
        if body == "sacrum":
            assert len(ours) > len(theirs) + 100, "the hip bones (MyoFullBody's pelvis) come with the sacrum"
    assert checked > 20000


def test_wrap_arcs_lie_on_the_surface_and_have_the_wrap_length(model):
    layout = model.path_layout
    drawing = Drawing(model)
    rng = np.random.default_rng(4)
    wrapped = 0
    for _ in range(20):
        q = np.r_[0.0, rng.uniform(-0.3, 0.3, 5)]
        R, p = drawing.poses(q)
        points = model.path_points(q)
        centre = np.einsum("wij,wj->wi", R[layout.wrap_body], layout.wrap_pos) + p[layout.wrap_body]
        axis = np.einsum("wij,wj->wi", R[layout.wrap_body], layout.wrap_rot[:, :, 2])
        arcs = wrap_arcs(points.tangents, points.wrap_lengths, centre, axis, layout.wrap_radius, layout.wrap_cylinder, 2001)
        on = points.wrap_lengths >= 0
        wrapped += on.sum()
        np.testing.assert_allclose(arcs[:, 0], points.tangents[:, 0], atol=1e-12)
        np.testing.assert_allclose(arcs[on, -1], points.tangents[on, 1], atol=1e-9)
        length = np.linalg.norm(np.diff(arcs, axis=1), axis=2).sum(axis=1)
        np.testing.assert_allclose(length[on], points.wrap_lengths[on], rtol=1e-5, atol=1e-9)
        radial = arcs - centre[:, None]
        radial -= np.where(layout.wrap_cylinder[:, None, None], np.sum(radial * axis[:, None], axis=2)[..., None] * axis[:, None], 0)
        np.testing.assert_allclose(np.linalg.norm(radial, axis=2)[on], np.broadcast_to(layout.wrap_radius[:, None], arcs.shape[:2])[on],
                                   rtol=1e-9)
    assert wrapped > 100


# ------------------------------------------------------------------------------ the page

def test_animation_page_structure(model, result, page):
    html = page.read_text()
    assert external_urls(html) == []
    assert not re.search(r"<(?:script|link|img|iframe|source|audio|video)\b[^>]*\s(?:src|href)\s*=", html), "the page loads no file"
    messages = scene_messages(html)
    objects = {m["path"]: m["object"] for m in messages if m["type"] == "set_object"}
    # every muscle, as a line through all its polyline vertices
    data = player(html)
    for i, name in enumerate(model.muscles):
        path = next(p for p in objects if p.endswith(f"/muscles/{model.spec.muscles[i].group}/{name}"))
        n_points = len(objects[path]["geometries"][0]["data"]["attributes"]["position"]["array"].data) // 12
        assert n_points == len(data["vertices"][i]) >= 2, name
    # every body with bones, as its mesh
    for body in bone_meshes():
        assert any(p.endswith(f"/{body}") and o["geometries"][0]["type"] == "_meshfile_geometry" for p, o in objects.items()), body
    assert "/platform" in objects
    # the recording: one frame per result sample, the result's duration, real time
    (animation,) = [m for m in messages if m["type"] == "set_animation"]
    assert animation["options"]["play"]
    n, fps = len(result.time), 1 / (result.time[1] - result.time[0])
    tracks = {a["path"]: a["clip"] for a in animation["animations"]}
    assert set(tracks) == {f"/passenger/bones/{s}" for s in ("sacrum", "lumbar5", "lumbar4", "lumbar3", "lumbar2", "lumbar1")} | {"/platform"}
    for clip in tracks.values():
        assert clip["fps"] == pytest.approx(fps)
        for track in clip["tracks"]:
            assert [k["time"] for k in track["keys"]] == list(range(n))
            assert (track["keys"][-1]["time"] - track["keys"][0]["time"]) / clip["fps"] == pytest.approx(DURATION)
    assert data["frames"] == n and data["fps"] == pytest.approx(fps)
    # the recorded platform follows the result's platform displacement
    platform = np.array([k["value"] for k in tracks["/platform"]["tracks"][0]["keys"]])
    np.testing.assert_allclose(np.linalg.norm(platform - platform[0], axis=1), np.abs(result.platform[:, 0] - result.platform[0, 0]), atol=1e-12)
    # the wrap points the player moves are the model's tangent points at every frame (int16: < 20 um)
    wrap = np.frombuffer(base64.b64decode(data["wrap"]["data"]), "<i2").reshape(n, -1, ARC_POINTS, 3)
    wrap = wrap * data["wrap"]["scale"] + np.array(data["wrap"]["offset"])
    for k in (0, n // 2, n - 1):
        points = model.path_points(result.q[k])
        on = points.wrap_lengths >= 0
        np.testing.assert_allclose(wrap[k, on][:, [0, -1]], points.tangents[on], atol=2e-5)
    activation = np.frombuffer(base64.b64decode(data["activation"]["data"]), np.uint8).reshape(n, -1) / 255 * data["activation"]["scale"]
    np.testing.assert_allclose(activation, np.clip(result.activation, 0, data["activation"]["scale"]), atol=data["activation"]["scale"] / 500)


def test_animation_plays_in_headless_chromium(page, tmp_path):
    """Chromium opens the page offline: the scene loads, no JavaScript error, and between t = 0
    and t = 1 s the picture changes where the upper trunk moved and nowhere outside the passenger."""
    from trunk_drake.visual import browser

    if browser.chromium_path() is None:
        pytest.skip("no chromium on PATH: .ci/run installs Debian's chromium with apt-get (needs root)")
    pytest.importorskip("playwright.sync_api", reason="Python playwright (test extra) drives Chromium")
    from PIL import Image

    def picture(tab):
        return np.asarray(Image.open(tab.screenshot(tmp_path / "shot.png")).convert("RGB"), dtype=float)

    with browser.open_page(page) as tab:
        boxes, shots = [], []
        for t in (0.0, DURATION):
            tab.seek(t)
            shots.append(picture(tab))
            boxes.append(tab.page.evaluate(SCREEN_BOXES))
        tab.page.evaluate("['passenger', 'platform'].forEach((p) => viewer.scene_tree.find([p]).set_property('visible', false));"
                          "viewer.set_dirty()")
        background = picture(tab)
    assert tab.errors == [], tab.errors
    assert all(u.startswith(("file:", "data:")) for u in tab.requests), [u for u in tab.requests if not u.startswith(("file:", "data:"))]
    changed = np.abs(shots[0] - shots[1]).sum(axis=2) > 40
    upper = _union(boxes[0]["upper"], boxes[1]["upper"])
    figure = _union(boxes[0]["figure"], boxes[1]["figure"], margin=6)
    inside = changed[upper[1]:upper[3], upper[0]:upper[2]]
    assert inside.size > 2000 and inside.mean() > 0.05, f"only {inside.mean():.1%} of the upper trunk's pixels changed"
    outside = changed.copy()
    outside[figure[1]:figure[3], figure[0]:figure[2]] = False
    assert outside.sum() == 0, f"{outside.sum()} pixels changed outside the passenger"
    drawn = (np.abs(shots[1] - background).sum(axis=2) > 40)[upper[1]:upper[3], upper[0]:upper[2]]
    assert drawn.mean() > 0.2, f"the passenger covers only {drawn.mean():.0%} of its upper trunk's box (blank canvas?)"


SCREEN_BOXES = """(() => {
  const THREE = MeshCat.THREE, w = window.innerWidth, h = window.innerHeight;
  const box = (names) => {
    const b = new THREE.Box3();
    names.forEach((path) => b.expandByObject(viewer.scene_tree.find(path).object));
    const out = [w, h, 0, 0];
    for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y]) for (const z of [b.min.z, b.max.z]) {
      const p = new THREE.Vector3(x, y, z).project(viewer.camera);
      const px = (p.x + 1) / 2 * w, py = (1 - p.y) / 2 * h;
      out[0] = Math.min(out[0], px); out[1] = Math.min(out[1], py); out[2] = Math.max(out[2], px); out[3] = Math.max(out[3], py);
    }
    return out;
  };
  viewer.scene.updateMatrixWorld(true);
  return {upper: box([["passenger", "bones", "lumbar1"]]), figure: box([["passenger"], ["platform"]])};
})()"""


def _union(a, b, margin=0):
    return [max(int(min(a[0], b[0])) - margin, 0), max(int(min(a[1], b[1])) - margin, 0),
            int(max(a[2], b[2])) + margin + 1, int(max(a[3], b[3])) + margin + 1]


def _obj_vertices(path) -> np.ndarray:
    return np.array([ln.split()[1:4] for ln in path.read_text().splitlines() if ln.startswith("v ")], dtype=float)


# ------------------------------------------------------------------------------ commands and live view

@pytest.mark.parametrize("dofs", ["sagittal", "spine3d", "rhythm"])
def test_view_command_writes_the_model_at_rest(dofs, tmp_path, capsys):
    from trunk_drake.cli import main

    path = tmp_path / "model.html"
    assert main(["view", "--dofs", dofs, "--out", str(path)]) == 0
    assert str(path) in capsys.readouterr().out
    html = path.read_text()
    assert external_urls(html) == []
    messages = scene_messages(html)
    assert not any(m["type"] == "set_animation" for m in messages)
    lines = [m["path"] for m in messages if m["type"] == "set_object" and "/muscles/" in m["path"]]
    assert sorted(p.rsplit("/", 1)[1] for p in lines) == sorted(td.load_model(dofs).muscles)
    meshes = {m["path"].rsplit("/", 1)[1] for m in messages if m["type"] == "set_object" and "/bones/" in m["path"]}
    assert meshes == set(bone_meshes())


def test_simulate_html_flag(tmp_path):
    from trunk_drake.cli import main

    assert main(["simulate", "--duration", "0.3", "--out", str(tmp_path), "--html"]) == 0
    data = player((tmp_path / "animation.html").read_text())
    assert data["frames"] == 31 and data["fps"] == pytest.approx(100)


def test_live_view_follows_its_sliders(model):
    from trunk_drake.visual import LiveView

    live = LiveView(model)
    assert live.url.startswith("http://localhost:")
    assert not live.update()
    live.meshcat.SetSliderValue("L1_L2_FE", 0.3)
    assert live.update() and live.q[model.coordinates.index("L1_L2_FE")] == pytest.approx(0.3, abs=0.01)  # slider step
    shown = [m for m in scene_messages(live.meshcat.StaticHtml()) if m["type"] == "set_transform" and m["path"] == "/passenger/bones/lumbar1"]
    R, p = Drawing(model).poses(live.q)
    lumbar1 = model.body_names.index("lumbar1")
    np.testing.assert_allclose(np.array(shown[-1]["matrix"]).reshape(4, 4).T[:3], np.column_stack([R[lumbar1], p[lumbar1]]), atol=1e-12)


def test_animate_rejects_what_it_cannot_show(model, result, tmp_path):
    import dataclasses

    uneven = dataclasses.replace(result, time=result.time ** 1.1)
    with pytest.raises(ValueError, match="uniform time grid"):
        td.animate(uneven, tmp_path / "a.html", model)
    alien = dataclasses.replace(result, coordinates=["hip_flexion", *result.coordinates[1:]])
    with pytest.raises(ValueError, match=r"coordinates \['hip_flexion'\]"):
        td.animate(alien, tmp_path / "a.html", model)


def test_bone_meshes_are_converted_once_into_the_user_cache(tmp_path, monkeypatch):
    from trunk_drake.visual import meshes

    monkeypatch.setenv("TRUNK_DRAKE_CACHE", str(tmp_path))
    first = meshes.bone_meshes()
    assert all(p.is_file() and p.parent.parent == tmp_path for p in first.values())
    monkeypatch.setattr(meshes, "_convert", lambda folder: pytest.fail("converted again"))
    assert meshes.bone_meshes() == first


def test_measured_motion_moves_a_second_trunk(model, result, tmp_path):
    """Data and model side by side: the data's trunk follows the trial's level angles (or, with the
    total rotation only, that rotation spread evenly over the levels), frame by frame."""
    from trunk_drake.io.trials import LUMBAR_LEVELS, Trial
    from trunk_drake.visual import measured_motion

    data = td.simulate(model, duration=DURATION, stiffness=400.0)  # stiffer: moves less than `result`
    levels = {c: data.coordinate(c)[::2] for c in LUMBAR_LEVELS}  # 50 Hz data
    trials = {"levels": Trial(time=data.time[::2], fs=50.0, platform_displacement=data.platform[::2, 0], levels=levels),
              "total": Trial(time=data.time[::2], fs=50.0, platform_displacement=data.platform[::2, 0],
                             lumbar_rotation=data.lumbar_rotation[::2])}
    lumbar1 = model.body_names.index("lumbar1")
    for kind, trial in trials.items():
        html = td.animate(result, tmp_path / f"{kind}.html", model, measured=measured_motion(trial, "trial 1")).read_text()
        messages = scene_messages(html)
        ghost = [m for m in messages if m["type"] == "set_object" and m["path"].startswith("/data/bones/")]
        assert {m["path"].rsplit("/", 1)[1] for m in ghost} == set(bone_meshes())
        assert all(m["object"]["materials"][0]["transparent"] for m in ghost)
        assert not any(m["path"].startswith("/data/muscles") for m in messages if m["type"] == "set_object")
        position = recorded_positions(html)["/data/bones/lumbar1"]
        assert len(position) == len(result.time)
        q_end = np.r_[data.platform[-1, 0], [data.coordinate(c)[-1] for c in LUMBAR_LEVELS]]
        if kind == "total":
            q_end[1:] = data.lumbar_rotation[-1] / 5
        _, p = Drawing(model).poses(q_end)
        np.testing.assert_allclose(position[-1], p[lumbar1], atol=1e-12)
        assert ("measured level angles" if kind == "levels" else "spread evenly") in html


def test_animate_trial_resimulates_the_data_with_the_given_options(model, tmp_path):
    """Data made by the model itself: re-simulated from the trial's sampled platform motion with the
    same options, the model's trunk and the data's coincide."""
    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.io.trials import LUMBAR_LEVELS, Trial
    from trunk_drake.visual import animate_trial

    options = TrunkOptions(stiffness=400.0, kp={"sacrospinalis": 0.5})
    data = td.simulate(model, duration=DURATION, bandwidth=3.0, options=options)
    trial = Trial(time=data.time, fs=100.0, platform_displacement=data.platform[:, 0],
                  levels={c: data.coordinate(c) for c in LUMBAR_LEVELS}, source="self.csv")
    html = animate_trial(trial, tmp_path / "trial.html", model, options).read_text()
    tracks = recorded_positions(html)
    model_l1, data_l1 = tracks["/passenger/bones/lumbar1"], tracks["/data/bones/lumbar1"]
    assert np.ptp(data_l1[:, 1]) > 0.005  # the trunk moved (m)
    np.testing.assert_allclose(model_l1, data_l1, atol=2e-4)


def test_view_serve_answers_on_its_port_until_ctrl_c():
    """`trunk-drake view --serve --port N` (the console script, as its own process): once it prints its address, the
    live Meshcat on port N serves the model at rest (its page's scene: every muscle of the --dofs configuration);
    Ctrl-C stops it with exit status 0 and no traceback."""
    with socket.socket() as s:  # a free port (released before the server takes it)
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    script = Path(sys.executable).with_name("trunk-drake")
    # a terminal's Ctrl-C: the child must not inherit an ignored SIGINT (as under `nohup ... &`, how CI may run)
    process = subprocess.Popen([str(script), "view", "--serve", "--port", str(port), "--dofs", "rhythm"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline, line = time.monotonic() + 120.0, ""
        while not line.startswith("Meshcat: open") and time.monotonic() < deadline and process.poll() is None:
            if select.select([process.stdout], [], [], 1.0)[0]:
                line = process.stdout.readline()
        assert line.startswith(f"Meshcat: open http://localhost:{port}"), (line, process.poll())
        page = urllib.request.urlopen(f"http://localhost:{port}/download", timeout=30).read().decode()
        objects = [m["path"] for m in scene_messages(page) if m["type"] == "set_object"]
        assert sorted(p.rsplit("/", 1)[1] for p in objects if "/muscles/" in p) == sorted(td.load_model("rhythm").muscles)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0 and "Traceback" not in err, err


def test_the_commands_that_draw_refuse_an_osim_model_before_the_work(lumbar_c210_path, tmp_path, capsys, monkeypatch):
    """Drawing is implemented for MyoTorso's muscle paths only: `view --model FILE.osim` and `simulate --model FILE.osim
    --html` give one error line, the latter before it simulates (diagnose's animations: tests/test_commands.py)."""
    import trunk_drake.simulation
    from trunk_drake.cli import main

    def refuse(*args, **kwargs):
        raise AssertionError("the work started before the input was checked")

    monkeypatch.setattr(trunk_drake.simulation, "simulate", refuse)
    for command in (["view", "--dofs", "rhythm", "--out", str(tmp_path / "model.html")],
                    ["simulate", "--html", "--duration", "0.1", "--out", str(tmp_path / "sim")]):
        assert main([*command, "--model", str(lumbar_c210_path)]) == 2, command
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith("trunk-drake: error: ") and "MyoTorso's" in err, err
    assert not (tmp_path / "model.html").exists()
