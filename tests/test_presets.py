"""Presets: every setting sourced, references checked, the command line overriding single settings."""

import pytest

from trunk_drake.cli import build_parser
from trunk_drake.commands import passenger_preset
from trunk_drake.presets import SETTINGS, load_preset


@pytest.mark.parametrize("name", ["default", "thesis"])
def test_every_setting_says_where_it_comes_from(name):
    preset = load_preset(name)
    assert set(preset.provenance) == set(SETTINGS)
    for key, origin in preset.provenance.items():
        assert origin.startswith(("models/reference_values.toml", "models/", "modelling choice: ")), (key, origin)


def test_a_value_that_contradicts_its_reference_is_refused(tmp_path):
    text = (load_preset.__globals__["preset_path"]("thesis")).read_text().replace("value = 125.0", "value = 120.0")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=r"\[stiffness\] value 120.0 differs from its reference"):
        load_preset(str(path))


def test_a_setting_without_a_source_is_refused(tmp_path):
    path = tmp_path / "bare.toml"
    path.write_text("\n".join(f"[{key}]\nvalue = 1.0\n" for key in SETTINGS))
    with pytest.raises(ValueError, match=r"\[dofs\] needs 'reference'"):
        load_preset(str(path))


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(FileNotFoundError, match=r"presets: \[.*'default'.*'thesis'"):
        load_preset("nonesuch")


def test_command_line_options_override_single_settings():
    args = build_parser().parse_args(["simulate", "--out", "x", "--stiffness", "300", "--l-desired", "1", "--no-reflex"])
    preset = passenger_preset(args)
    assert preset.name == "default (modified)" and preset.stiffness == 300.0 and preset.l_desired == 1.0
    assert preset.reflex_gains is None and preset.gains() == {"kp": 0.0, "kv": 0.0}
    assert preset.provenance["stiffness"] == "set by the user" and preset.provenance["damping"] != "set by the user"
    assert passenger_preset(build_parser().parse_args(["simulate", "--out", "x", "--preset", "thesis"])).dofs == "sagittal"
