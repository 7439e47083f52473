"""The `mitsuba` method (Mitsuba volpath at equal time) is timed fairly: its render kernel is
compiled and run once while loading (MitsubaVolpath._render reads the image back, which waits
for Dr.Jit's asynchronous launch), not inside the first timed iteration."""

from __future__ import annotations

import pytest

from renderer.methods.mitsuba import MitsubaVolpath
from renderer.mitsuba_env import import_mitsuba
from renderer.scene import load_scene


def test_loading_runs_the_render_kernel_once() -> None:
    mi = import_mitsuba()
    if mi.variant().startswith("scalar"):
        pytest.skip("scalar variants compile no kernels")
    import drjit as dr

    scene = load_scene("cbox-grid", ["film.width=16", "film.height=16"])
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # start empty
        method = MitsubaVolpath(scene, seed=3, threads=2, params={"spp_per_iteration": 2})
        loading = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    samples = 16 * 16 * method.spp_per_iteration
    assert any(k["type"] == dr.KernelType.JIT and k["size"] == samples for k in loading)


def test_it_renders_with_volpath_and_says_so() -> None:
    """What a user would run, volpath, also where the references render one grey scene per
    channel (extinction that differs between channels): the sidecar names it, as the
    reference's does."""
    scene = load_scene(
        "cbox-fog", ["film.width=8", "film.height=8", "media.fog.sigma_t=[0.2, 1, 3]"]
    )
    method = MitsubaVolpath(scene, seed=0, threads=1, params={"spp_per_iteration": 1})
    assert method.stats()["integrator"] == "volpath"
    assert str(method.scene.integrator()).startswith("VolumetricSimplePathIntegrator[")
