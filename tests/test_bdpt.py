"""bdpt (cpp/bdpt.h, methods/bdpt.py): the MIS weights of every strategy that can sample a
path sum to one, the strategies' unweighted images agree where they sample the same paths, and
the image agrees with pt's on every shipped scene and with Mitsuba's, at several depths."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_small
from parity import agreement, assert_block_check_has_power, mitsuba, ours, same_image
from renderer import _core
from renderer.methods import get_method
from renderer.methods.bdpt import BidirectionalPathTracing
from renderer.methods.pt import PathTracing

EMISSION, SURFACE, MEDIUM, CAMERA = 0, 1, 2, 3


def traced(name: str, extra: tuple[str, ...] = (), spp: int = 1, size: int = 8):
    """One iteration of bdpt's subpaths through scene `name`: the method and both records."""
    scene = load_small(name, size, size, extra)
    method = BidirectionalPathTracing(scene, seed=7, threads=2, params={"spp_per_iteration": spp})
    method.light_paths.run(0)
    method.camera_paths.run(0)
    return method, method.light_paths.kernel.vertices(), method.camera_paths.kernel.vertices()


def subpaths(records: dict) -> list[list[int]]:
    """Each subpath's record indices, in depth order."""
    order = np.lexsort((records["depth"], records["path"]))
    out: dict[int, list[int]] = {}
    for i in order:
        out.setdefault(int(records["path"][i]), []).append(int(i))
    return list(out.values())


def weights(method, records: dict, indices: list[int], taus: list[float], max_connect: int = 16):
    """The probe's weights of the path made of these records (from its light end)."""
    r = {k: records[k][indices] for k in ("position", "kind", "triangle", "medium", "light")}
    return _core.bdpt_path_weights(
        method.native.core,
        np.ascontiguousarray(r["position"]),
        np.ascontiguousarray(r["kind"].astype(np.uint8)),
        np.ascontiguousarray(r["triangle"].astype(np.int32)),
        np.ascontiguousarray(r["medium"].astype(np.int32)),
        np.ascontiguousarray(r["light"].astype(np.int32)),
        np.asarray(taus, np.float64),
        max_connect,
    )


def closed_camera_paths(method, camera: dict):
    """Camera subpaths that end on an area light, lit from its front: whole paths. Yields each
    as (records, indices from the light end, edge optical depths from the light end)."""
    for path in subpaths(camera):
        last = path[-1]
        if camera["kind"][last] != SURFACE or len(path) < 3:
            continue
        triangle = int(camera["triangle"][last])
        if not _emits(method, triangle, camera["wi"][last]):
            continue
        kinds, lights = camera["kind"].copy(), camera["light"].copy()
        kinds[last] = EMISSION  # the same point, as the light's own vertex
        lights[last] = _light_of(method, triangle)
        taus = [float(camera["tau_in"][i]) for i in path[1:]][::-1]
        yield dict(camera, kind=kinds, light=lights), path[::-1], taus


@pytest.mark.parametrize(
    "name, spp",
    [
        ("cbox-fog", 32),
        ("cbox-glass", 32),
        ("juice", 32),
        ("cbox-grid", 32),
        ("volcaustic", 256),
        ("fog-perlin", 32),
    ],  # fmt: skip
)
def test_weights_of_camera_paths_that_reach_a_light_sum_to_one(name, spp):
    """Camera subpaths that end on an area light make whole paths with surface, medium and
    delta (glass) vertices, through null boundaries, homogeneous and grid media, with the camera
    inside a medium (volcaustic): every strategy that can sample such a path gets a weight,
    and they sum to one."""
    method, _, camera = traced(name, spp=spp)
    checked = 0
    for records, light_order, taus in closed_camera_paths(method, camera):
        w = weights(method, records, light_order, taus)
        assert sum(weight for _, _, weight in w) == pytest.approx(1.0, rel=1e-9), (name, w)
        assert all(s + t == len(light_order) for s, t, _ in w)
        checked += 1
    assert checked >= 5, checked


@pytest.mark.parametrize(
    "name, extra",
    [
        ("smoke", ()),  # point lights in a density grid
        ("crepuscular", ()),  # a directional light through null windows
        (
            "cbox-fog",
            (
                "lights=[{type: spot, position: [0, 0.9, 0], target: [0, -1, 0], "
                "intensity: 5, cutoff_angle: 40}]",
            ),
        ),  # fmt: skip
        ("cbox-glass", ()),
    ],
    ids=["point", "directional", "spot", "area-glass"],
)
def test_weights_of_light_paths_joined_to_the_camera_sum_to_one(name, extra):
    """Light subpaths from every kind of light, closed by the camera (the junction's optical
    depth is arbitrary: the weights sum to one whatever it is, as long as every strategy sees
    the same)."""
    method, light, camera = traced(name, extra, spp=64)
    eye = int(np.flatnonzero(camera["kind"] == CAMERA)[0])
    # Only paths the camera can close: their last vertex projects onto the film.
    pixels, _ = _core.camera_projections(
        method.native.core, np.ascontiguousarray(light["position"])
    )
    checked = 0
    for path in subpaths(light):
        if len(path) < 2 or pixels[path[-1]] < 0:
            continue
        records = {k: np.concatenate([light[k], camera[k][eye : eye + 1]]) for k in light}
        taus = [float(light["tau_in"][i]) for i in path[1:]] + [0.37]
        w = weights(method, records, [*path, len(light["kind"])], taus)
        if not w:  # e.g. a path whose only junction is a delta vertex
            continue
        assert sum(weight for _, _, weight in w) == pytest.approx(1.0, rel=1e-9), (name, w)
        checked += 1
    assert checked >= 20, checked


@pytest.mark.parametrize("max_connect", [2, 3])
def test_connections_cut_at_max_connect_keep_the_weights_summing_to_one(max_connect):
    """Connections between more than max_connect vertices on a side are not made: the other
    strategies' weights make up for them."""
    method, _, camera = traced("cbox-fog", ("media.fog.sigma_t=3",), spp=256)
    checked = 0
    for records, light_order, taus in closed_camera_paths(method, camera):
        if len(light_order) < 2 * max_connect:
            continue
        w = weights(method, records, light_order, taus, max_connect=max_connect)
        assert sum(weight for _, _, weight in w) == pytest.approx(1.0, rel=1e-9)
        assert all(s < 2 or t < 2 or max(s, t) <= max_connect for s, t, _ in w)
        checked += 1
    assert checked >= 3, checked


def _emits(method, triangle: int, wi) -> bool:
    scene = method.scene
    owner = method.native.per_triangle(scene, list(range(len(scene.shapes))))[triangle]
    if scene.shapes[owner].emission is None:
        return False
    return float(np.dot(method.native.normals[triangle], wi)) > 0


def _light_of(method, triangle: int) -> int:
    """The core's light index of an emitting triangle's shape (area lights come first)."""
    scene = method.scene
    owner = int(method.native.per_triangle(scene, list(range(len(scene.shapes))))[triangle])
    return sum(1 for s in scene.shapes[:owner] if s.emission is not None)


def test_unweighted_strategies_agree_where_they_sample_the_same_paths():
    """On cbox (diffuse surfaces only) every strategy of a path length samples every path of
    that length: their unweighted images have the same mean (direct light: (0, 3), (1, 2),
    (2, 1); one bounce more: (0, 4), (1, 3), (2, 2), (3, 1))."""
    scene = load_small("cbox", 10, 10)
    method = get_method("bdpt")(
        scene, seed=3, threads=2, params={"spp_per_iteration": 8, "strategy_images": True}
    )
    per_iteration: dict[str, list[np.ndarray]] = {}
    previous: dict[str, np.ndarray] = {}
    for i in range(12):
        method.run_iteration(i)
        for name, image in method.extra_images().items():
            total = image * (i + 1)
            per_iteration.setdefault(name, []).append(total - previous.get(name, 0))
            previous[name] = total
    from parity import Estimate

    for length in (3, 4):
        names = [f"s{s}t{length - s}-unweighted" for s in range(length)]
        estimates = [Estimate(np.stack(per_iteration[n])) for n in names if n in per_iteration]
        assert len(estimates) == length, sorted(per_iteration)
        for other in estimates[1:]:
            result = agreement(estimates[0].image_mean(), other.image_mean())
            assert result.passes, (length, result)


SCENES = [
    "cbox",
    "cbox-fog",
    "cbox-glass",
    "cbox-grid",
    "crepuscular",
    "fog-perlin",
    "fog-step",
    "juice",
    "smoke",
    "volcaustic",
]


@pytest.mark.parametrize("name", SCENES)
def test_bdpt_agrees_with_pt(name):
    """Image mean and 3x3 blocks, against pt on every shipped scene (pt's own parity with
    Mitsuba covers these scenes: tests/test_parity.py)."""
    scene = load_small(name, 12, 12)
    bdpt = ours(BidirectionalPathTracing, scene, 16, seed=1, spp_per_iteration=8)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=32)
    ok, why = same_image(bdpt, pt, alpha=1e-3, block=4)
    assert ok, f"{name}: {why}"


@pytest.mark.parametrize("max_depth", [1, 2, 3, -1])
def test_bdpt_agrees_with_mitsuba_at_every_depth(max_depth):
    """cbox-fog (lights and surfaces inside a fog box, null boundary): bdpt against Mitsuba's
    volpath, max_depth 1 (emitters only), 2 (direct light and single scattering), 3 and
    unbounded; a 3 % darker block is caught."""
    scene = load_small("cbox-fog", 12, 12, (f"integrator.max_depth={max_depth}",))
    bdpt = ours(BidirectionalPathTracing, scene, 32, seed=1, spp_per_iteration=8)
    ref = mitsuba(scene, 16, 256)
    ok, why = same_image(bdpt, ref, alpha=1e-3, block=4)
    assert ok, f"max_depth {max_depth}: {why}"
    if max_depth == -1:
        assert_block_check_has_power(bdpt, ref, "bdpt cbox-fog", size=4)


def test_same_image_whatever_the_thread_count():
    images = []
    for threads in (1, 2):
        scene = load_small("cbox-glass", 8, 8)
        method = get_method("bdpt")(scene, seed=5, threads=threads, params={})
        for i in range(2):
            method.run_iteration(i)
        images.append(method.image())
    assert np.array_equal(*images) and images[0].max() > 0


def test_strategy_images_add_up_to_the_image(tmp_path):
    """`--set method.strategy_images=true` writes each strategy's weighted and unweighted image
    beside the output; the weighted ones add up to the image (the weights of every path sum to
    one, so every strategy's share is there and none twice)."""
    from renderer import cli
    from renderer.imageio import read_exr

    out = tmp_path / "box.exr"
    args = ["render", "cbox-fog", "--method", "bdpt", "--spp", "4", "-q", "-o", str(out),
            "--set", "film.width=12", "--set", "film.height=12",
            "--set", "method.strategy_images=true"]  # fmt: skip
    assert cli.main(args) == 0
    weighted = sorted(p for p in tmp_path.glob("box.s*t*.exr") if "unweighted" not in p.name)
    assert len(weighted) > 10
    assert all(p.with_name(p.stem + "-unweighted.exr").is_file() for p in weighted)
    total = sum(read_exr(p).astype(np.float64) for p in weighted)
    np.testing.assert_allclose(total, read_exr(out), rtol=1e-5, atol=1e-7)
    assert {"box.s0t3.exr", "box.s1t2.exr", "box.s1t1.exr", "box.s2t2.exr"} <= {
        p.name for p in weighted
    }
