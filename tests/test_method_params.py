"""Method parameters with a wrong type or out of range are one-line errors naming the method
and the key, raised before any work (every method reads them through MethodParams)."""

from __future__ import annotations

import pytest

from conftest import load_small
from renderer.errors import PgiError
from renderer.methods import get_method
from renderer.scene.model import Film

INT_1 = "an integer >= 1 and <= 2147483647"  # counts reach the core as 32-bit ints
INT_0 = "an integer >= 0 and <= 2147483647"
BAD = [
    ("pt", "spp_per_wave", 2**40, INT_1),
    ("pt", "spp_per_wave", "abc", INT_1),
    ("pt", "spp_per_wave", 0, INT_1),
    ("pt", "spp_per_wave", 2.5, INT_1),
    ("pt", "slots_per_lane", 0, "an integer >= 1 and <= 1048576"),
    ("pt", "slots_per_lane", 2**21, "an integer >= 1 and <= 1048576"),
    ("lt", "light_paths", [1, 2], INT_1),
    ("lt", "max_records", -1, INT_1),
    ("pm", "light_paths", True, INT_1),
    ("pm", "surface_radius_world", float("nan"), "a number >= "),  # 1e-9 of the scene's size
    ("pm", "volume_radius_world", 1e-160, "a number >= "),  # 1/(pi r^2) overflowed into NaN
    ("pm", "surface_radius_relative", "big", "a number >= 1e-09"),
    ("pm", "volume_radius_relative", 1e-160, "a number >= 1e-09"),
    ("ppb", "beam_radius_relative", 1e-160, "a number >= 1e-09"),
    # wider than the scene: every photon everywhere, 20x slower (found by a review)
    ("pm", "surface_radius_world", 1e30, "a number >= 1.73205e-09 and <= 3.4641"),  # cbox: sqrt 3
    ("pm", "surface_radius_relative", 3, "a number >= 1e-09 and <= 2"),
    ("ppb", "beam_radius_relative", 2.5, "a number >= 1e-09 and <= 2"),
    ("ppb", "beam_radius_world", 1e-12, "a number >= 1.73205e-09 and <= 3.4641"),
    ("ppb", "surface_radius_relative", 2.5, "a number >= 0 and <= 2"),
    ("ppb", "surface_radius_relative", 1e-160, "0 (path-traced surfaces) or >= 1e-09"),
    ("ppb", "surface_radius_world", 1e-160, "0 (path-traced surfaces) or >= 1.73205e-09"),
    ("sppm", "surface_alpha", 1.0, "a number > 0 and < 1"),
    ("sppm", "volume_alpha", None, "a number > 0 and < 1"),
    ("ppb", "light_paths", [1, 2], INT_1),
    ("ppb", "beam_alpha", 1.5, "a number > 0 and <= 1"),
    ("ppb", "surface_radius_relative", -0.1, "a number >= 0"),
    ("ppb", "gather_bounces", -1, INT_0),
    ("mitsuba", "spp_per_iteration", "4", INT_1),
    ("pm", "volume_radius_neighbours", 0, INT_1),
    ("sppm", "surface_radius_neighbours", 2.5, INT_1),
    ("ppb", "beam_radius_neighbours", -3, INT_1),
    ("vpl", "light_paths", 0, INT_1),
    ("vpl", "spp_per_iteration", 1.5, INT_1),
    ("vpl", "share_lights", "yes", "true or false"),
    ("vpl", "clamp_distance_world", 0, "a number >= 1.73205e-09 and <= 3.4641"),
    ("vsl", "max_records", 0, INT_1),
    ("vsl", "free_flight_fraction", -0.5, "a number >= 0 and < 1"),
    ("vsl", "sphere_radius_world", float("inf"), "a number >= 1.73205e-09 and <= 3.4641"),
    ("vrl", "min_depth", 0, INT_1),
    ("vbl", "min_depth", "3", INT_1),
]


@pytest.mark.parametrize("method, key, value, expected", BAD)
def test_bad_method_parameter_is_a_clear_error(method, key, value, expected):
    with pytest.raises(PgiError) as info:
        get_method(method)(load_small("cbox", 4, 4), seed=0, threads=1, params={key: value})
    msg = str(info.value)
    assert msg.startswith(f"method {method}: {key} must be {expected}") and ", got " in msg, msg


def test_a_bad_value_is_quoted_as_yaml_writes_it_and_briefly():
    """Values come from --set and config files: quoted as Python wrote them, true was `True`,
    and a 3000-element list made a 17,000-character line (a review)."""
    for value, quoted in ((True, "got true"), (None, "got null"), (list(range(3000)), "...")):
        with pytest.raises(PgiError) as info:
            get_method("pt")(
                load_small("cbox", 4, 4), seed=0, threads=1, params={"spp_per_wave": value}
            )
        assert str(info.value).endswith(quoted) and len(str(info.value)) < 200, info.value


@pytest.mark.parametrize(
    "method, params, message",
    [
        ("ppb", {"gather_bounces": 1}, "gather_bounces has no effect unless with path-traced"),
        (
            "ppb",
            {"surface_radius_relative": 0, "surface_alpha": 0.5},
            "surface_alpha has no effect with path-traced surfaces",
        ),
        (
            "pm",
            {"surface_radius_world": 0.1, "surface_radius_relative": 0.02},
            "give surface_radius_world or surface_radius_relative, not both",
        ),
        (
            "sppm",
            {"radius_scale": 0.02, "volume_radius_relative": 0.1},
            "radius_scale is an old name of volume_radius_relative: give only one",
        ),
        # the pilot's k nearest photons derive a radius that is not given
        (
            "pm",
            {"volume_radius_world": 0.1, "volume_radius_neighbours": 8},
            "volume_radius_neighbours has no effect with volume_radius_world or "
            "volume_radius_relative",
        ),
        (
            "ppb",
            {"surface_radius_relative": 0, "surface_radius_neighbours": 8},
            "surface_radius_neighbours has no effect with path-traced surfaces",
        ),
    ],
)
def test_a_parameter_without_effect_or_given_twice_is_an_error(method, params, message):
    with pytest.raises(PgiError, match=f"^method {method}: {message}"):
        get_method(method)(load_small("cbox", 4, 4), seed=0, threads=1, params=params)


def test_sppm_takes_both_radii_without_its_default_scale():
    sppm = get_method("sppm")(
        load_small("cbox", 4, 4),
        seed=0,
        threads=1,
        params={"surface_radius_world": 0.1, "volume_radius_world": 0.2},
    )
    assert (sppm.surface_given, sppm.volume_given) == (0.1, 0.2)


@pytest.mark.parametrize(
    "method, old, value, new",
    [
        ("pm", "photons", 64, {"light_paths": 64}),
        ("pm", "radius", 0.1, {"surface_radius_world": 0.1}),
        ("sppm", "volume_radius", 0.1, {"volume_radius_world": 0.1}),
        (
            "pm",
            "radius_scale",
            0.03,
            {"surface_radius_relative": 0.03, "volume_radius_relative": 0.03},
        ),
        ("sppm", "alpha", 0.5, {"surface_alpha": 0.5, "volume_alpha": 0.5}),
        ("ppb", "radius", 0.02, {"beam_radius_relative": 0.02}),
        ("ppb", "alpha", 0.7, {"beam_alpha": 0.7}),
        ("ppb", "surface_radius", 0.03, {"surface_radius_relative": 0.03}),
        ("ppb", "piece_length", 0.3, {"piece_length_relative": 0.3}),
    ],
)
def test_old_parameter_names_still_work_with_a_warning(method, old, value, new, capsys):
    """Renamed parameters (one vocabulary: radii say whether they are world units or relative
    to the scene, light paths are light paths): the old name sets the new ones and says so."""
    m = get_method(method)(load_small("cbox", 4, 4), seed=0, threads=1, params={old: value})
    for key, v in new.items():
        assert m.method_params[key] == pytest.approx(v), key
    assert old not in m.method_params
    err = capsys.readouterr().err
    assert f"pgi: warning: method {method}: {old} is an old name: use " in err, err
    assert all(f"{key}=" in err for key in new if key != "volume_alpha"), err


@pytest.mark.parametrize(
    "method, key, value",
    [
        ("pt", "spp_per_wave", 1_000_000),  # 256 million paths at 64 bytes: 15 GiB
        ("pm", "spp_per_iteration", 100_000),
        ("pm", "light_paths", 10**8),
        ("sppm", "spp_per_iteration", 100_000),
        ("ppb", "light_paths", 10**8),
        ("ppb", "spp_per_iteration", 100_000),
        ("lt", "light_paths", 10**8),
        ("mitsuba", "spp_per_iteration", 500_000),  # one LLVM wavefront holds them all
        ("vpl", "light_paths", 10**8),
        ("vsl", "spp_per_iteration", 100_000),
    ],
)
def test_batches_beyond_half_the_memory_are_refused_before_any_work(
    monkeypatch, method, key, value
):
    """On a 16x16 film: 25.6 million camera paths (or 1e8 light paths) per batch, ~15 GiB at
    the bound of 640 bytes a path (pt: 256 million paths of 64 bytes; Mitsuba: 128 million
    samples of 128 bytes), on a machine of 24 GiB; Linux used to grant the memory and then
    kill the render."""
    import renderer.methods.params as params

    monkeypatch.setattr(params, "physical_memory", lambda: 24 * 2**30)
    with pytest.raises(PgiError, match=f"^method {method}: {key} gives batches of .* GiB"):
        get_method(method)(load_small("cbox", 16, 16), seed=0, threads=1, params={key: value})


def test_every_parameter_used_is_recorded_with_its_value():
    """The sidecar's `method_params`: given and default values alike (its `params` holds only
    those given), and none whose default plays no part (a review)."""
    scene = load_small("cbox", 4, 4)
    pm = get_method("pm")(scene, seed=0, threads=1, params={"light_paths": 100})
    assert pm.method_params == {
        "light_paths": 100,
        "spp_per_iteration": 1,
        "max_records": 8388608,
        "surface_radius_neighbours": 32,
        "volume_radius_neighbours": 32,
    }
    both = get_method("pm")(
        scene, seed=0, threads=1, params={"surface_radius_world": 0.1, "volume_radius_world": 0.2}
    )
    assert "surface_radius_relative" not in both.method_params
    assert "surface_radius_neighbours" not in both.method_params  # no pilot: radii given
    assert both.method_params["volume_radius_world"] == 0.2
    sppm = get_method("sppm")(scene, seed=0, threads=1, params={"surface_alpha": 0.5})
    assert sppm.method_params["surface_alpha"] == sppm.method_params["volume_alpha"] == 0.5
    assert "light_paths" in sppm.method_params
    ppb = get_method("ppb")(scene, seed=0, threads=1, params={"surface_radius_relative": 0})
    assert "gather_bounces" in ppb.method_params and "surface_alpha" not in ppb.method_params


def test_a_film_that_fits_at_one_sample_per_pixel_is_rendered(monkeypatch):
    """The bound was 1 KiB per camera path for every method, Mitsuba included: a 4096x4096
    film was refused on 24 GiB (measured: pt 475 bytes a path, Mitsuba 84-94 a sample),
    with advice to lower a samples-per-iteration parameter that was already 1 (a review)."""
    import renderer.methods.params as params
    from renderer.methods.mitsuba import MitsubaVolpath

    monkeypatch.setattr(params, "physical_memory", lambda: 24 * 2**30)
    film = Film(4096, 4096)
    params.MethodParams("pt", {}, ()).camera_paths_fit_in_memory("spp_per_wave", 1, film)
    scene = load_small("cbox", 4096, 4096)
    assert MitsubaVolpath.check_parameters(scene, {}) == 1
    assert MitsubaVolpath.check_parameters(scene, {"spp_per_iteration": 4}) == 4
    # at one sample per pixel the film alone can be made smaller
    with pytest.raises(PgiError, match=r"about 21 GiB, .*: lower the film's size$"):
        params.MethodParams("pt", {}, ()).camera_paths_fit_in_memory(
            "spp_per_wave", 1, Film(6000, 6000)
        )
    with pytest.raises(PgiError, match="lower method.spp_per_iteration or the film's size$"):
        MitsubaVolpath.check_parameters(scene, {"spp_per_iteration": 8})


def test_memory_bound_follows_the_machine(monkeypatch):
    import renderer.methods.params as params

    monkeypatch.setattr(params, "physical_memory", lambda: 2**40)  # 1 TiB: 100,000 spp fits
    params.MethodParams("pt", {}, ()).paths_fit_in_memory("spp_per_wave", 25_600_000)
    # light paths keep their records: 3.3 KB each measured for ppb, bounded by 4 KiB, so on
    # 24 GiB 2 million fit and 4 million (16 GiB) do not; 12 million used to pass
    monkeypatch.setattr(params, "physical_memory", lambda: 24 * 2**30)
    params.MethodParams("ppb", {}, ()).light_paths_fit_in_memory("light_paths", 2_000_000)
    with pytest.raises(PgiError, match="gives batches of 4,000,000 light paths, about 15 GiB"):
        params.MethodParams("ppb", {}, ()).light_paths_fit_in_memory("light_paths", 4_000_000)
    monkeypatch.setattr(params, "physical_memory", lambda: 2**30)  # 1 GiB: 1e6 paths do not
    with pytest.raises(PgiError, match="more than half this machine's 1 GiB"):
        params.MethodParams("pt", {}, ()).paths_fit_in_memory("spp_per_wave", 10**6)
    # lt's default batch under an spp budget is a whole number of paths per pixel: the film's
    # size sets it, and the message says so (it named light_paths alone)
    with pytest.raises(PgiError, match="lower method.light_paths or the film's size$"):
        get_method("lt")(load_small("cbox", 1024, 1024), seed=0, threads=1, params={},
                         spp_budget=1)  # fmt: skip


def test_pt_bounds_its_wave_paths_and_its_film(monkeypatch):
    """pt keeps path state only for its lanes' slots: 24 bytes per path of a wave (bounded at
    64) and its film, image and writing 58 a pixel (bounded at 128). On 24 GiB an 8000x8000
    film fits at one sample per pixel per wave (the 640-byte bound refused 4600x4600), and
    9000x9000 is refused before any work, for the film's size."""
    import renderer.methods.params as params
    from renderer.methods.pt import PathTracing

    monkeypatch.setattr(params, "physical_memory", lambda: 24 * 2**30)
    args = (params.PT_WAVE_PATH_BYTES, params.PT_PIXEL_BYTES)
    params.MethodParams("pt", {}, ()).camera_paths_fit_in_memory(
        "spp_per_wave", 1, Film(8000, 8000), *args
    )
    with pytest.raises(PgiError, match=r"about 14 GiB, .*: lower the film's size$"):
        PathTracing(load_small("cbox", 9000, 9000), seed=0, threads=1, params={})


def test_a_reference_too_large_for_memory_is_refused_before_mitsuba(monkeypatch):
    """`pgi reference` had no bound: a 16384x16384 film crashed Mitsuba (exit 139, no
    message; an error-handling probe). It is refused before Mitsuba starts, for the film's
    size; 4096x4096 (one sample a pass) fits on 24 GiB."""
    import renderer.methods.params as params
    from renderer import reference

    monkeypatch.setattr(params, "physical_memory", lambda: 24 * 2**30)
    monkeypatch.setattr(reference, "import_mitsuba", lambda: pytest.fail("Mitsuba started"))
    reference.check_reference_fits_in_memory(load_small("cbox", 4096, 4096), 1)
    with pytest.raises(PgiError, match=r"16384x16384 .* about 38 GiB, .*: lower the film's size$"):
        reference.render_reference(load_small("cbox", 16384, 16384), spp=1)
