"""Tests for trunk_drake.io: OpenSim storage / CSV round trips, measured-trial loading."""

import math

import numpy as np
import pytest

from trunk_drake.io import (
    LUMBAR_LEVELS,
    StorageData,
    load_trial,
    read_csv,
    read_storage,
    read_table,
    write_csv,
    write_storage,
    write_table,
)


def _random_table(n=57, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    cols = {
        "L5_S1_FE": rng.normal(size=n) * 0.05,
        "pelvis_tx": rng.normal(size=n) * 1e-3,
        "tiny": rng.normal(size=n) * 1e-300,
        "huge": rng.normal(size=n) * 1e200,
        "third": np.full(n, 1.0 / 3.0),
    }
    return StorageData.from_columns(t, cols, in_degrees=False, name="test_table")


# ----------------------------------------------------------------------------- storage


@pytest.mark.parametrize("ext", [".sto", ".mot"])
def test_storage_round_trip_exact(tmp_path, ext):
    d = _random_table()
    p = tmp_path / f"data{ext}"
    write_storage(p, d, in_degrees=True)
    text = p.read_text().splitlines()
    assert text[0] == "test_table"
    assert "version=1" in text and "nRows=57" in text and "nColumns=6" in text
    assert "inDegrees=yes" in text
    end = text.index("endheader")
    assert text[end + 1].split("\t") == ["time", "L5_S1_FE", "pelvis_tx", "tiny", "huge", "third"]
    r = read_storage(p)
    assert r.labels == d.labels
    assert r.in_degrees is True
    assert r.name == "test_table"
    assert r.header["nRows"] == "57"
    np.testing.assert_allclose(r.time, d.time, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.data, d.data, rtol=1e-12, atol=0)
    assert np.array_equal(r.data, d.data)  # 17 significant digits: exact
    # the file-line bookkeeping points at the first data row
    assert r.line_of_row(0) == end + 3
    # dispatch by extension gives the same
    r2 = read_table(p)
    assert np.array_equal(r2.data, r.data)


def test_storage_write_from_columns_and_nan(tmp_path):
    p = tmp_path / "x.sto"
    write_table(p, time=[0.0, 0.5], columns={"a": [1.0, np.nan]})
    r = read_storage(p)
    assert r.in_degrees is False
    assert r.data[0, 0] == 1.0 and np.isnan(r.data[1, 0])
    np.testing.assert_array_equal(r.column("a")[:1], [1.0])


def test_read_opensim_style_files(tmp_path):
    # OpenSim 4 style with leading whitespace and extra header entries
    p = tmp_path / "ik.mot"
    p.write_text(
        "Coordinates\nversion=1\nnRows=3\nnColumns=3\ninDegrees=yes\n\n"
        "Units are S.I. units (second, meters, Newtons, ...)\nendheader\n"
        "time\tL4_L5_FE\tpelvis_tx\n"
        "      0.00000000\t     1.50000000\t     0.00100000\n"
        "      0.01000000\t     2.00000000\t     0.00200000\n"
        "      0.02000000\t     2.50000000\t     0.00300000\n"
    )
    r = read_storage(p)
    assert r.in_degrees is True and r.name == "Coordinates"
    np.testing.assert_allclose(r.column("L4_L5_FE"), [1.5, 2.0, 2.5])
    # old (pre-4.0) header style, space separated
    q = tmp_path / "old.mot"
    q.write_text("name old\ndatacolumns 2\ndatarows 2\nrange 0 1\nendheader\ntime force\n0 1\n1 2\n")
    r = read_storage(q)
    assert r.name == "old" and r.header["datarows"] == "2" and r.in_degrees is None
    np.testing.assert_allclose(r.column("force"), [1, 2])


def test_storage_read_errors(tmp_path):
    p = tmp_path / "noend.sto"
    p.write_text("x\nversion=1\ntime\ta\n0\t1\n")
    with pytest.raises(ValueError, match="endheader"):
        read_storage(p)
    p = tmp_path / "ragged.sto"
    p.write_text("x\nversion=1\nendheader\ntime\ta\tb\n0\t1\t2\n0.1\t1\n")
    with pytest.raises(ValueError, match=r"line 6.*\['b'\]"):
        read_storage(p)
    p = tmp_path / "text.sto"
    p.write_text("x\nendheader\ntime\ta\n0\t1\n0.1\tabc\n")
    with pytest.raises(ValueError, match=r"line 5, column 'a'.*'abc'"):
        read_storage(p)
    with pytest.warns(UserWarning, match="nRows"):
        p = tmp_path / "count.sto"
        p.write_text("x\nnRows=5\nendheader\ntime\ta\n0\t1\n")
        read_storage(p)


def test_csv_round_trip(tmp_path):
    d = _random_table(seed=3)
    p = tmp_path / "d.csv"
    write_csv(p, d, metadata={"subject": "S01"})
    r = read_csv(p)
    assert r.labels == d.labels
    assert r.in_degrees is False and r.header["subject"] == "S01"
    np.testing.assert_allclose(r.data, d.data, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.time, d.time, rtol=1e-12, atol=0)
    # plain CSV without metadata, time not first, other time label
    q = tmp_path / "plain.csv"
    q.write_text("a,Time\n1,0\n2,0.1\n")
    r = read_table(q)
    assert r.labels == ["a"] and r.in_degrees is None
    np.testing.assert_allclose(r.time, [0, 0.1])
    q.write_text("a,b\n1,0\n")
    with pytest.raises(ValueError, match="time_column"):
        read_csv(q)
    np.testing.assert_allclose(read_csv(q, time_column="b").column("a"), [1])


def test_unknown_extension(tmp_path):
    with pytest.raises(ValueError, match="extension"):
        read_table(tmp_path / "x.xlsx")


# ----------------------------------------------------------------------------- trials


def _write_trial_csv(path, n=200, fs=100.0, disp_scale=1.0, deg=True, extra_cols=None):
    t = np.arange(n) / fs
    disp = 0.02 * np.sin(2 * np.pi * 0.5 * t) * disp_scale
    ang = np.array([0.5, 0.8, 1.0, 1.2, 1.5])[:, None] * np.sin(2 * np.pi * 0.5 * t)[None]  # deg
    cols = {"time": t, "platform_displacement": disp}
    for lv, a in zip(LUMBAR_LEVELS, ang):
        cols[lv + ("_deg" if deg else "")] = a
    cols["emg_LTpL_l"] = np.abs(np.sin(t))
    cols["marker_x"] = t * 2
    cols.update(extra_cols or {})
    lines = [",".join(cols)]
    for i in range(n):
        lines.append(",".join(repr(float(v[i])) for v in cols.values()))
    path.write_text("\n".join(lines) + "\n")
    return t, disp, ang


def test_load_trial_csv_degrees_suffix(tmp_path):
    p = tmp_path / "trial.csv"
    t, disp, ang = _write_trial_csv(p)
    tr = load_trial(p)
    assert tr.fs == pytest.approx(100.0)
    np.testing.assert_allclose(tr.time, t)
    np.testing.assert_allclose(tr.platform_displacement, disp)
    assert tr.perturbation_name == "platform_displacement"
    assert list(tr.levels) == list(LUMBAR_LEVELS)
    np.testing.assert_allclose(tr.levels["L3_L4_FE"], np.radians(ang[2]))
    np.testing.assert_allclose(tr.total_lumbar_rotation(), np.radians(ang.sum(axis=0)))
    assert tr.lumbar_rotation is None
    assert set(tr.emg) == {"LTpL_l"}
    assert set(tr.extra) == {"marker_x"}
    assert tr.column_map["L5_S1_FE"] == "L5_S1_FE_deg"
    assert tr.conversions["L5_S1_FE"] == pytest.approx(math.pi / 180)


def test_load_trial_sto_in_degrees(tmp_path):
    n = 100
    t = np.arange(n) / 50.0
    d = StorageData.from_columns(
        t,
        {"pelvis_tx": 0.01 * np.sin(t), "lumbar_rotation": 10 * np.sin(t), "trunk_in_space": 3 * np.cos(t)},
        in_degrees=True,
    )
    p = tmp_path / "trial.mot"
    write_storage(p, d)
    tr = load_trial(p)
    np.testing.assert_allclose(tr.lumbar_rotation, np.radians(10 * np.sin(t)), rtol=1e-12)
    np.testing.assert_allclose(tr.trunk_in_space, np.radians(3 * np.cos(t)), rtol=1e-12)
    np.testing.assert_allclose(tr.pelvis_displacement, 0.01 * np.sin(t))  # translations: metres
    assert tr.total_lumbar_rotation() is tr.lumbar_rotation
    with pytest.raises(ValueError, match="inDegrees=yes.*angle_units"):
        load_trial(p, angle_units="rad")


def test_load_trial_displacement_in_mm_is_an_error(tmp_path):
    p = tmp_path / "mm.csv"
    _write_trial_csv(p, disp_scale=1000.0)  # 20 mm amplitude written as 20.0
    with pytest.raises(ValueError, match=r"'platform_displacement'.*row \d+.*_mm"):
        load_trial(p)
    tr = load_trial(p, displacement_units="mm")
    assert np.max(np.abs(tr.platform_displacement)) == pytest.approx(0.02, rel=1e-3)


def test_load_trial_mm_suffix_converts(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("time,pelvis_tx_mm,L4_L5_FE_rad\n0,10,0.01\n0.01,20,0.02\n0.02,30,0.03\n")
    tr = load_trial(p)
    np.testing.assert_allclose(tr.pelvis_displacement, [0.01, 0.02, 0.03])
    np.testing.assert_allclose(tr.levels["L4_L5_FE"], [0.01, 0.02, 0.03])


def test_load_trial_degrees_without_suffix_is_an_error(tmp_path):
    p = tmp_path / "deg.csv"
    _write_trial_csv(p, deg=False)
    # 1.5 deg amplitude passes as radians, so make it implausible: 45 "rad"
    text = p.read_text().splitlines()
    hdr = text[0].split(",")
    j = hdr.index("L1_L2_FE")
    row = text[5].split(",")
    row[j] = "45.0"
    text[5] = ",".join(row)
    p.write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError, match=r"'L1_L2_FE', row 5 \(line 6\).*_deg"):
        load_trial(p)
    tr = load_trial(p, angle_units="deg")
    assert tr.levels["L1_L2_FE"][4] == pytest.approx(math.radians(45.0))


def test_load_trial_nan_names_column_and_row(tmp_path):
    p = tmp_path / "nan.csv"
    p.write_text("time,platform_displacement,lumbar_rotation\n0,0,0\n0.01,0.001,0.01\n0.02,,0.02\n0.03,0.002,0.03\n")
    with pytest.raises(ValueError, match=r"'platform_displacement', row 3 \(line 4\).*missing"):
        load_trial(p)


def test_load_trial_ragged_columns(tmp_path):
    # a column that stops early (empty trailing fields): unequal lengths
    p = tmp_path / "ragged.csv"
    p.write_text(
        "time,platform_displacement,L4_L5_FE\n0,0,0\n0.01,0.001,0.01\n0.02,0.002,\n0.03,0.003,\n"
    )
    with pytest.raises(ValueError, match=r"'L4_L5_FE'.*row 3.*unequal length"):
        load_trial(p)
    # rows with fewer fields than the header
    q = tmp_path / "short.csv"
    q.write_text("time,platform_displacement,L4_L5_FE\n0,0,0\n0.01,0.001\n")
    with pytest.raises(ValueError, match=r"line 3.*\['L4_L5_FE'\].*ragged"):
        load_trial(q)


def test_load_trial_time_checks(tmp_path):
    p = tmp_path / "nonuni.csv"
    p.write_text("time,platform_displacement,L4_L5_FE\n0,0,0\n0.01,0,0\n0.02,0,0\n0.05,0,0\n0.06,0,0\n")
    with pytest.raises(ValueError, match=r"row 4.*non-uniform sampling.*resample"):
        load_trial(p)
    p.write_text("time,platform_displacement,L4_L5_FE\n0,0,0\n0.01,0,0\n0.01,0,0\n0.02,0,0\n")
    with pytest.raises(ValueError, match=r"'time', row 3.*strictly increasing"):
        load_trial(p)


def test_load_trial_missing_and_ambiguous_columns(tmp_path):
    p = tmp_path / "noresp.csv"
    p.write_text("time,platform_displacement\n0,0\n0.01,0\n")
    with pytest.raises(ValueError, match="no lumbar angle column"):
        load_trial(p)
    assert load_trial(p, require_response=False).platform_displacement is not None
    p.write_text("time,L4_L5_FE\n0,0\n0.01,0\n")
    with pytest.raises(ValueError, match="no perturbation column"):
        load_trial(p)
    p.write_text("time,platform_x,platform_displacement_mm,L4_L5_FE\n0,0,0,0\n0.01,0,0,0\n")
    with pytest.raises(ValueError, match="both look like platform_displacement"):
        load_trial(p)
    tr = load_trial(p, columns={"platform_displacement": "platform_x"})
    assert tr.column_map["platform_displacement"] == "platform_x"
    assert "platform_displacement_mm" in tr.extra
    # explicit mapping of a non-standard label
    p.write_text("time,Xplat,theta_deg\n0,0,0\n0.01,0.001,1\n")
    tr = load_trial(p, columns={"platform_displacement": "Xplat", "lumbar_rotation": "theta_deg"})
    assert tr.lumbar_rotation[1] == pytest.approx(math.radians(1.0))
    with pytest.raises(ValueError, match="not a column"):
        load_trial(p, columns={"platform_displacement": "nope"})


def test_prepared_trials_are_named_by_their_files_not_their_paths():
    """Results key trials by name: a file's name is the same on every machine, its absolute path is not."""
    from trunk_drake.io.prepared import trial_names

    assert trial_names(["/a/b/trial_1.csv", "/a/b/trial_2.csv", None]) == ["trial_1.csv", "trial_2.csv", "trial 2"]
    assert trial_names(["/a/x.csv", "/b/x.csv", "c/y.csv"]) == ["/a/x.csv", "/b/x.csv", "y.csv"]  # only clashes keep paths
