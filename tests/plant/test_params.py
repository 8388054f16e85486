"""Motor parameters: validation of every field, preset files, overrides, TOML motor files."""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.hil.drive_params import DRIVE_FIELDS, DriveParams, flat_values
from pmsm_hil.hil.errors import HilError, InputFileError, ParameterError
from pmsm_hil.hil.machine import params_class_for_kind
from pmsm_hil.hil.motor_params import SETTABLE_UNITS, PmsmParams, parse_set_options
from pmsm_hil.hil.presets_loader import load_motor, preset_names

BASE = PmsmParams.build(rs=1.0, ld=0.01, lq=0.012, psi_f=0.2, pole_pairs=3, vdc=300.0, j=0.001)
POSITIVE = ("rs", "ld", "lq", "vdc", "j", "i_trip", "speed_trip_rpm")
NON_NEGATIVE = ("psi_f", "b", "t_dead", "t_mpw", "rated_speed_rpm", "rated_torque_nm", "lls", "speed_kp", "speed_ki")
NUMERIC_FIELDS = sorted(PmsmParams.parameter_names())


def _make(**changes: Any) -> PmsmParams:
    values = flat_values(BASE)
    values.update(changes)
    return PmsmParams.build(**values)


def test_every_numeric_field_is_covered_by_a_rule() -> None:
    assert set(NUMERIC_FIELDS) == {*POSITIVE, *NON_NEGATIVE, "pole_pairs"}
    assert set(SETTABLE_UNITS) <= set(NUMERIC_FIELDS)


@pytest.mark.parametrize("name", POSITIVE)
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_positive_fields_reject_zero_and_negative(name: str, value: float) -> None:
    with pytest.raises(ParameterError, match=f"'{name}' must be > 0"):
        _make(**{name: value})


@pytest.mark.parametrize("name", NON_NEGATIVE)
def test_non_negative_fields_reject_negative_and_accept_zero(name: str) -> None:
    with pytest.raises(ParameterError, match=f"'{name}' must be ≥ 0"):
        _make(**{name: -1e-9})
    assert getattr(_make(**{name: 0.0}), name) == 0.0


@pytest.mark.parametrize("name", [*POSITIVE, *NON_NEGATIVE])
@pytest.mark.parametrize("value", [math.nan, math.inf, "1.0", True, None])
def test_float_fields_reject_non_finite_and_non_numbers(name: str, value: object) -> None:
    with pytest.raises(ParameterError, match=f"'{name}' must be a finite number"):
        _make(**{name: value})


@pytest.mark.parametrize("value", [0, -3, 2.5, 3.0, True, "3"])
def test_pole_pairs_must_be_an_integer_at_least_one(value: object) -> None:
    with pytest.raises(ParameterError, match="'pole_pairs' must be an integer ≥ 1"):
        _make(pole_pairs=value)


@pytest.mark.parametrize("name", ["t_dead", "t_mpw"])
def test_dead_time_and_min_pulse_are_seconds_below_1ms(name: str) -> None:
    with pytest.raises(ParameterError, match="t_dead'/'t_mpw'"):
        _make(**{name: 2.5})  # µs typed as s
    assert getattr(_make(**{name: 2.5e-6}), name) == 2.5e-6


def test_every_kind_contains_one_drive_whose_fields_read_as_its_own() -> None:
    """PMSM (both layouts), induction machine and flux map: one DriveParams each; `params.j` is `params.drive.j`."""
    for name in preset_names():
        params = load_motor(name)
        assert isinstance(params.drive, DriveParams), name
        assert {k: getattr(params, k) for k in DRIVE_FIELDS} == {k: getattr(params.drive, k) for k in DRIVE_FIELDS}
        assert set(DRIVE_FIELDS) <= params.parameter_names()
    assert load_motor("im-2k2").drive.speed_trip_rpm == 3000.0  # the kind's own defaults
    changed = BASE.with_values(j=0.002, rs=2.0)
    assert (changed.j, changed.drive.j, changed.rs, changed.vdc) == (0.002, 0.002, 2.0, BASE.vdc)
    assert BASE.with_overrides({"j": 0.003}).drive.j == 0.003


def test_saliency_and_torque() -> None:
    assert BASE.is_salient and not _make(lq=0.01).is_salient
    # Te = 1.5 p (ψf iq + (Ld − Lq) id iq)
    assert BASE.torque_nm(-2.0, 5.0) == pytest.approx(1.5 * 3 * (0.2 * 5.0 + (0.01 - 0.012) * -2.0 * 5.0))


@pytest.mark.parametrize("name", preset_names())
def test_presets_give_every_parameter_a_value_unit_and_source(name: str) -> None:
    text = (resources.files("pmsm_hil.hil.presets") / f"{name}.toml").read_text(encoding="utf-8")
    doc = tomllib.loads(text)
    assert doc["name"] == name and doc["description"]
    table = doc["parameters"]
    params_class = params_class_for_kind(doc.get("kind", "three-phase"))
    file_keys = getattr(params_class, "FILE_KEYS", ())
    assert set(table) == params_class.parameter_names() - set(file_keys)
    for key, entry in table.items():
        assert isinstance(entry, dict), key
        assert isinstance(entry["value"], (int, float)) and not isinstance(entry["value"], bool), key
        assert isinstance(entry["unit"], str), key
        assert key == "pole_pairs" or entry["unit"], f"{key} needs a unit"
        assert isinstance(entry["source"], str) and len(entry["source"]) > 5, key
    params = load_motor(name)  # the preset loads as its own kind's parameter class, with the file's values
    assert isinstance(params, params_class)
    for key, entry in table.items():
        assert getattr(params, key) == entry["value"], key
    assert params.name == name


def test_preset_units_agree_with_settable_units() -> None:
    for name in preset_names():
        doc = tomllib.loads((resources.files("pmsm_hil.hil.presets") / f"{name}.toml").read_text("utf-8"))
        for key, unit in params_class_for_kind(doc.get("kind", "three-phase")).SETTABLE_UNITS.items():
            assert doc["parameters"][key]["unit"] == unit, (name, key)


def test_bundled_presets_are_listed() -> None:
    assert {"niu2020-ipmsm", "xiao2023-spmsm"} <= set(preset_names())


def test_niu2020_vdc_decision_covers_rated_point() -> None:
    p = load_motor("niu2020-ipmsm")
    w_e = p.pole_pairs * p.rated_speed_rpm * math.pi / 30
    iq = p.rated_torque_nm / (1.5 * p.pole_pairs * p.psi_f)
    v = math.hypot(-w_e * p.lq * iq, p.rs * iq + w_e * p.psi_f)
    assert v < p.vdc / math.sqrt(3)  # rated point inside the inverter's linear range


def test_overrides_replace_values_and_keep_the_rest() -> None:
    p = load_motor("niu2020-ipmsm", {"rs": 3.0, "pole_pairs": 4.0, "t_dead": 1e-6})
    base = load_motor("niu2020-ipmsm")
    assert (p.rs, p.pole_pairs, p.t_dead) == (3.0, 4, 1e-6)
    assert isinstance(p.pole_pairs, int)
    assert p.with_values(rs=base.rs, pole_pairs=base.pole_pairs, t_dead=base.t_dead) == base


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [({"ld": -1.0}, "'ld' must be > 0"), ({"pole_pairs": 2.5}, "'pole_pairs' must be an integer"),
     ({"foo": 1.0}, "unknown motor parameter 'foo'"), ({"name": 1.0}, "unknown motor parameter 'name'"),
     ({"vdc": 0.0}, "'vdc' must be > 0"), ({"t_mpw": 3.0}, "t_mpw")],
)
def test_bad_overrides_name_the_parameter(overrides: dict[str, float], fragment: str) -> None:
    with pytest.raises(ParameterError, match=fragment):
        load_motor("niu2020-ipmsm", overrides)


def test_parse_set_options() -> None:
    parsed = parse_set_options(["rs=1.5", " ld = 2e-3", "pole_pairs=4"])
    assert parsed == {"rs": 1.5, "ld": 2e-3, "pole_pairs": 4.0}
    assert parse_set_options(None) == {}


@pytest.mark.parametrize(
    ("item", "fragment"),
    [("rs", "NAME=VALUE"), ("=3", "NAME=VALUE"), ("rs=abc", "--set rs: value 'abc' is not a number"),
     ("rs=nan", "--set rs: value must be finite"), ("rs=inf", "finite")],
)
def test_parse_set_options_errors(item: str, fragment: str) -> None:
    with pytest.raises(ParameterError, match=fragment):
        parse_set_options([item])


def test_unknown_preset_lists_the_bundled_ones() -> None:
    with pytest.raises(ParameterError, match=r"unknown motor preset 'nope'.*niu2020-ipmsm"):
        load_motor("nope")


GOOD_TOML = """name = "bench motor"
[parameters]
rs = { value = 1.0, unit = "Ω", source = "test" }
ld = 0.01
lq = 0.01
psi_f = 0.1
pole_pairs = 2
vdc = 48
j = 1e-4
"""


def test_toml_file_loads_with_plain_or_table_values(tmp_path: Path) -> None:
    path = tmp_path / "m.toml"
    path.write_text(GOOD_TOML, encoding="utf-8")
    p = load_motor(str(path), {"vdc": 60.0})
    assert (p.name, p.rs, p.pole_pairs, p.vdc, p.b) == ("bench motor", 1.0, 2, 60.0, 0.0)


@pytest.mark.parametrize(
    ("text", "fragment"),
    [("not toml [", "m.toml"), ("name = 'x'\n", "missing [parameters]"),
     (GOOD_TOML.replace("ld = 0.01\n", ""), "missing parameter(s) ld"),
     (GOOD_TOML + "zz = 1\n", "unknown parameter(s) zz"),
     (GOOD_TOML.replace("rs = { value = 1.0,", "rs = { value = 'one',"), "'rs' needs a numeric value"),
     (GOOD_TOML.replace("pole_pairs = 2", "pole_pairs = 2.5"), "'pole_pairs' must be an integer"),
     (GOOD_TOML.replace("j = 1e-4", "j = -1e-4"), "'j' must be > 0"),
     (GOOD_TOML.replace("vdc = 48", "vdc = true"), "'vdc' needs a numeric value")],
)
def test_bad_toml_files_name_the_file_and_key(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError) as exc:
        load_motor(str(path))
    assert fragment in str(exc.value)
    assert str(path) in str(exc.value)


def test_missing_toml_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="No such file"):
        load_motor(str(tmp_path / "absent.toml"))


def test_errors_share_the_hil_base_class() -> None:
    assert issubclass(ParameterError, HilError) and issubclass(InputFileError, HilError)
