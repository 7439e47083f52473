"""Method parameters with a wrong type or out of range are one-line errors naming the method
and the key, raised before any work (every method reads them through MethodParams)."""

from __future__ import annotations

import pytest

from conftest import load_small
from renderer.errors import PgiError
from renderer.methods import get_method

BAD = [
    ("pt", "spp_per_wave", "abc", "an integer >= 1"),
    ("pt", "spp_per_wave", 0, "an integer >= 1"),
    ("pt", "spp_per_wave", 2.5, "an integer >= 1"),
    ("lt", "light_paths", [1, 2], "an integer >= 1"),
    ("lt", "max_records", -1, "an integer >= 1"),
    ("pm", "photons", True, "an integer >= 1"),
    ("pm", "radius", float("nan"), "a number > 0"),
    ("pm", "radius_scale", "big", "a number > 0"),
    ("sppm", "alpha", 1.0, "a number > 0 and < 1"),
    ("sppm", "volume_alpha", None, "a number > 0 and < 1"),
    ("ppb", "light_paths", [1, 2], "an integer >= 1"),
    ("ppb", "alpha", 1.5, "a number > 0 and <= 1"),
    ("ppb", "surface_radius", -0.1, "a number >= 0"),
    ("ppb", "gather_bounces", -1, "an integer >= 0"),
    ("mitsuba", "spp_per_iteration", "4", "an integer >= 1"),
]


@pytest.mark.parametrize("method, key, value, expected", BAD)
def test_bad_method_parameter_is_a_clear_error(method, key, value, expected):
    with pytest.raises(PgiError) as info:
        get_method(method)(load_small("cbox", 4, 4), seed=0, threads=1, params={key: value})
    msg = str(info.value)
    assert msg.startswith(f"method {method}: {key} must be {expected}, got "), msg
