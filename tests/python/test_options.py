"""stampede.Options: the ini file's keys, values and validation."""

import os

import pytest

import stampede


def test_keys_values_and_canonical_text():
    o = stampede.Options(renderer="exact", psf_fwhm=2.85, psf_e2=0.05, minimizer_max_iterations=150)
    assert o["renderer"] == "exact"
    assert o["psf_fwhm"] == "2.85"
    assert o["minimizer_max_iterations"] == "150"
    assert sorted(o.explicitly_set()) == ["minimizer_max_iterations", "psf_e2", "psf_fwhm", "renderer"]
    d = o.to_dict()
    assert list(d) == list(stampede.option_help())  # every key, in documentation order
    assert "renderer" in o and "no_such_key" not in o


def test_dict_and_keywords_and_replace():
    o = stampede.Options({"psf_e1": 0.01}, psf_e2=0.02)
    assert (o["psf_e1"], o["psf_e2"]) == ("0.01", "0.02")
    p = o.replace(psf_e1=-0.03)
    assert (p["psf_e1"], o["psf_e1"]) == ("-0.03", "0.01")
    assert stampede.Options(psf_pixel_integrated=False)["psf_pixel_integrated"] == "false"


def test_floats_keep_full_precision():
    x = 0.1 + 0.2  # 0.30000000000000004: str() of a float would lose nothing, %g would
    assert float(stampede.Options(psf_e1=x)["psf_e1"]) == x


def test_unknown_key_is_a_config_error_naming_it():
    with pytest.raises(stampede.ConfigError, match="unknown option 'psf_fhwm'") as e:
        stampede.Options(psf_fhwm=2.85)
    assert isinstance(e.value, ValueError) and isinstance(e.value, stampede.Error)


def test_bad_value_names_key_and_value():
    with pytest.raises(ValueError, match="minimizer_max_iterations.*'many'"):
        stampede.Options(minimizer_max_iterations="many")
    with pytest.raises(stampede.ConfigError, match="psf_fwhm"):
        stampede.Options(psf_fwhm=-1.0)  # parses, breaks the constraint: validated on construction
    with pytest.raises(stampede.ConfigError, match="psf_beta"):
        stampede.Options(psf_beta=None)


def test_from_ini(tmp_path):
    ini = tmp_path / "run.ini"
    ini.write_text("renderer = exact\npsf_e2 = 0.05  # GalSim-mini\n")
    o = stampede.Options.from_ini(str(ini), psf_e1=0.01)
    assert (o["renderer"], o["psf_e2"], o["psf_e1"]) == ("exact", "0.05", "0.01")
    ini.write_text("renderer = fast\n")
    with pytest.raises(stampede.ConfigError, match="run.ini:1: option 'renderer'"):
        stampede.Options.from_ini(str(ini))
    with pytest.raises(stampede.ConfigError, match="cannot read config file"):
        stampede.Options.from_ini(os.path.join(str(tmp_path), "missing.ini"))


def test_options_argument_forms():
    with pytest.raises(TypeError, match="options must be"):
        stampede.fit_stamps([[[0.0]]], options=["renderer", "exact"])
    with pytest.raises(stampede.ConfigError, match="unknown option"):
        stampede.fit_stamps([[[1.0]]], options={"nope": 1})
