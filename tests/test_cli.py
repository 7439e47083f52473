"""The pgi command as a user meets it: outputs, sidecars, and clear errors on bad input."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import SCENES
from renderer.errors import PgiError
from renderer.progressive import available_cores

PGI = [sys.executable, "-m", "renderer.cli"]


def pgi(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([*PGI, *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def small(*extra: str) -> list[str]:
    return ["--set", "film.width=16", "--set", "film.height=16", *extra]


def test_render_writes_image_sidecar_and_snapshots(tmp_path):
    out = tmp_path / "fog.exr"
    r = pgi(
        "render",
        "cbox-fog",
        "--method",
        "pt",
        "--snapshots",
        "0.2,0.4",
        "--threads",
        "1",
        "--seed",
        "5",
        "-q",
        *small(),
        "-o",
        str(out),
    )
    assert r.returncode == 0, r.stderr
    for path in (out, tmp_path / "fog.t0.2.exr", tmp_path / "fog.t0.4.exr"):
        assert path.exists() and path.with_suffix(".json").exists()
    info = json.loads(out.with_suffix(".json").read_text())
    for key in (
        "method",
        "params",
        "iterations",
        "spp",
        "render_seconds",
        "load_seconds",
        "rays",
        "nonfinite",
        "seed",
        "threads",
        "version",
        "scene",
    ):
        assert key in info
    assert info["method"] == "pt" and info["seed"] == 5 and info["nonfinite"] == 0
    # every method parameter with the value used, though none was given
    assert info["params"] == {} and set(info["method_params"]) == {"spp_per_wave", "slots_per_lane"}
    # the code it ran: `version` alone is the same for every commit
    assert info["code"] == json.loads(pgi("fingerprint").stdout)["render"]
    # the final image is the iteration end nearest 0.4 s
    assert info["render_seconds"] + info["last_iteration_seconds"] / 2 >= 0.4
    assert info["nonfinite"] == 0 and info["rays"] > 0
    snap = json.loads((tmp_path / "fog.t0.2.json").read_text())
    assert snap["snapshot_budget"] == 0.2 and snap["render_seconds"] <= info["render_seconds"]


def test_render_spp_budget_and_image_content(tmp_path):
    from renderer.imageio import read_exr

    out = tmp_path / "box.exr"
    r = pgi(
        "render",
        str(SCENES / "cbox" / "scene.yaml"),
        "--method",
        "pt",
        "--spp",
        "4",
        "-q",
        *small(),
        "-o",
        str(out),
    )
    assert r.returncode == 0, r.stderr
    image = read_exr(out)
    assert image.shape == (16, 16, 3) and np.all(np.isfinite(image)) and image.mean() > 0
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["spp"] == 4
    # Without --threads a render uses every core it may, as `pgi reference` does.
    assert info["threads"] == available_cores()


def test_methods_lists_pt_and_mitsuba():
    r = pgi("methods")
    assert r.returncode == 0
    ids = [line.split()[0] for line in r.stdout.splitlines()]
    assert "pt" in ids and "mitsuba" in ids
    from renderer.known_methods import NOT_YET_IMPLEMENTED

    planned = "# not yet implemented: " + ", ".join(NOT_YET_IMPLEMENTED)
    assert (r.stdout.splitlines()[-1] == planned) == bool(NOT_YET_IMPLEMENTED)


def test_method_table_in_the_docs_matches_pgi_methods():
    """docs/methods.md's method table is the one `pgi methods` and scenes refer to."""
    from renderer.known_methods import NOT_YET_IMPLEMENTED
    from renderer.methods import method_ids

    text = (Path(__file__).resolve().parents[1] / "docs" / "methods.md").read_text()
    table = text.split("## The method table", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|") for line in table.splitlines() if line.startswith("| `")]
    status = {cells[1].strip().strip("`"): cells[4].strip() for cells in rows}
    assert status == {
        **{m: "implemented" for m in method_ids()},
        **{m: "not yet" for m in NOT_YET_IMPLEMENTED},
    }


BAD_SCENES = {
    "broken-yaml": ("camera: [unclosed\n", "scene.yaml"),
    "unknown-key": (None, "colour"),
    "missing-mesh": (None, "missing.ply"),
    "negative-density": (None, "sigma_t"),
}


def _write_bad_scene(tmp_path: Path, kind: str) -> Path:
    base = (SCENES / "cbox-fog" / "scene.yaml").read_text()
    folder = tmp_path / kind
    folder.mkdir()
    (folder / "box.yaml").write_text((SCENES / "cbox" / "box.yaml").read_text())
    base = base.replace("../cbox/box.yaml", "box.yaml")
    if kind == "broken-yaml":
        text = BAD_SCENES[kind][0]
    elif kind == "unknown-key":
        text = base + "colour: blue\n"
    elif kind == "missing-mesh":
        text = base.replace(
            "shapes:\n",
            "shapes:\n  - {name: bunny, type: mesh, file: missing.ply, material: white}\n",
            1,
        )
    else:
        text = base.replace("sigma_t: 1.0", "sigma_t: -1.0")
    (folder / "scene.yaml").write_text(text)
    return folder / "scene.yaml"


@pytest.mark.parametrize("kind", sorted(BAD_SCENES))
def test_bad_scene_gives_one_line_error_and_no_output(tmp_path, kind):
    scene = _write_bad_scene(tmp_path, kind)
    out = tmp_path / "out.exr"
    r = pgi("render", str(scene), "--method", "pt", "--spp", "1", "-o", str(out))
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    message = r.stderr.strip()
    assert message.startswith("pgi: error:") and len(message.splitlines()) == 1, message
    assert "scene.yaml" in message and BAD_SCENES[kind][1] in message
    assert not any(tmp_path.glob("out*")), "nothing may be written on error"
    v = pgi("validate", str(scene))
    assert v.returncode != 0 and "Traceback" not in v.stderr
    assert len(v.stderr.strip().splitlines()) == 1 and BAD_SCENES[kind][1] in v.stderr, v.stderr


@pytest.mark.parametrize(
    "args, expected",
    [
        (["render", "cbox", "--method", "nope", "--spp", "1", "-o", "x.exr"], "unknown method"),
        (["render", "cbox", "--method", "pt", "-o", "x.exr"], "--time, --spp or --snapshots"),
        (["render", "cbox", "--method", "pt", "--spp", "1", "-o", "x.png"], ".exr"),
        (
            ["render", "no-such-scene", "--method", "pt", "--spp", "1", "-o", "x.exr"],
            "no-such-scene",
        ),
        (
            ["render", "cbox", "--method", "pt", "--spp", "1", "--threads", "999", "-o", "x.exr"],
            "core",
        ),
        (["compare", "missing-a.exr", "missing-b.exr"], "missing-a.exr"),
        (
            ["validate", "cbox", "--set", "method.beam_radius_relative=1"],
            "apply to `pgi render` only",
        ),
        (["render", "cbox", "--method", "pt", "--time", "nan", "-o", "x.exr"], "finite"),
        (["render", "cbox", "--method", "pt", "--spp", "1", "--seed", "-1", "-o", "x.exr"], "2^63"),
        (["compare", "a.png", "b.exr"], "expected a linear .exr image"),
        (
            ["render", "cbox", "--method", "pt", "--spp", "1", "-o", "x.exr"]
            + ["--set", "shapes[7].transform=[{scale: 1.0e-9}, {translate: [0, 1000, 0]}]"],
            "every triangle of this emitter is degenerate",
        ),
        (
            ["render", "cbox-grid", "--method", "pt", "--spp", "1", "-o", "x.exr"]
            + ["--set", "integrator.estimator=raymarch", "--set", "integrator.march_step=1e-9"],
            "integrator.march_step: 1e-09 is below",
        ),
        (
            ["render", "cbox", "--method", "pt", "--time", "1", "--snapshots", "1,2"]
            + ["-o", "x.exr"],
            "beyond --time 1",
        ),
        (
            [
                "reference",
                "cbox",
                "--spp",
                "1",
                "--set",
                "method.beam_radius_relative=1",
                "-o",
                "r.exr",
            ],
            "apply to `pgi render` only",
        ),
        (["reference", "cbox", "--spp", "1", "--threads", "999", "-o", "r.exr"], "core"),
        (
            ["render", "cbox", "--method", "pt", "--snapshots", "1,1.0000001", "-o", "x.exr"],
            "--snapshots: 1.0 s and 1.0000001 s share the file name x.t1.exr",
        ),
        (
            ["render", "cbox", "--method", "pt", "--snapshots", "0.1,,0.2", "-o", "x.exr"],
            "expected comma-separated seconds, got '0.1,,0.2'",
        ),
        (["render", "cbox", "--method", "pt"], "required: -o/--output"),
        # an option the command does not know points to that command's help
        (
            ["render", "cbox", "--method", "pt", "--bogus", "-o", "x.exr"],
            "pgi render: error: unrecognized arguments: --bogus (see `pgi render --help`)",
        ),
        (["render", "cbox", "--method", "pt", "--spp", "1.5", "-o", "x.exr"], "an integer"),
        # a section of the wrong type is a mistake, not an empty section
        (
            ["render", "cbox", "--method", "pt", "--spp", "1", "--set", "lights=0", "-o", "x.exr"],
            "lights: expected a list of lights, got 0",
        ),
    ],
)
def test_user_mistakes_are_one_line_errors(tmp_path, args, expected):
    r = pgi(*args, cwd=tmp_path)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr and expected in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not list(tmp_path.iterdir())
    if args[0] == "render" and "--set" in args:  # validate rejects what render rejects
        scene_args = [args[1]] + [a for i, a in enumerate(args) if "--set" in args[i - 1 : i]]
        v = pgi("validate", *[x for a in scene_args[1:] for x in ("--set", a)], scene_args[0])
        assert v.returncode == 2 and expected in v.stderr, v.stderr


def test_unreadable_method_parameter_says_why_in_one_short_line(tmp_path):
    deep = "[" * 5000 + "]" * 5000
    item = f"method.spp_per_wave={deep}"
    r = pgi(
        "render", "cbox", "--method", "pt", "--spp", "1", "--set", item, "-o", "x.exr", cwd=tmp_path
    )
    assert r.returncode == 2 and not list(tmp_path.iterdir())
    assert r.stderr == (
        "pgi: error: --set method.spp_per_wave: value '" + "[" * 36 + "... is not valid YAML"
        " (nested too deeply)\n"
    )
    r = pgi("validate", "cbox", "--set", item)
    assert (
        r.stderr
        == "pgi: error: --set method.spp_per_wave: method parameters apply to `pgi render` only\n"
    )


def test_images_that_are_not_whole_exr_files_are_refused(tmp_path):
    """A truncated EXR (its pixels fail to decode) and a PNG named .exr: no metrics, and one
    line that says why."""
    from renderer.imageio import write_exr

    rng = np.random.default_rng(0)
    write_exr(tmp_path / "ref.exr", rng.uniform(size=(64, 64, 3)))
    data = (tmp_path / "ref.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    (tmp_path / "header.exr").write_bytes(data[:100])  # cut inside the header
    (tmp_path / "empty.exr").write_bytes(b"")
    import OpenImageIO as oiio

    oiio.ImageBuf(oiio.ImageSpec(8, 8, 3, oiio.UINT8)).write(str(tmp_path / "p.png"))
    (tmp_path / "p.png").rename(tmp_path / "png.exr")
    for name, expected in (("cut.exr", "cannot read pixels"), ("png.exr", "found png"),
                           ("header.exr", "a corrupt or truncated OpenEXR file"),
                           ("empty.exr", "the file is empty")):  # fmt: skip
        r = pgi("compare", str(tmp_path / name), str(tmp_path / "ref.exr"))
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert f"pgi: error: {tmp_path / name}: " in r.stderr and expected in r.stderr
        assert r.stdout == "", r.stdout
        # one line: OpenEXR's own decoding errors, which it prints itself, go into ours
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    # A grey EXR is read as three equal channels: against a colour image that is a mistake.
    grey = oiio.ImageBuf(oiio.ImageSpec(64, 64, 1, oiio.FLOAT))
    grey.set_pixels(oiio.ROI(0, 64, 0, 64, 0, 1, 0, 1), rng.uniform(size=(64, 64, 1)).astype("f4"))
    grey.write(str(tmp_path / "grey.exr"))
    r = pgi("compare", str(tmp_path / "grey.exr"), str(tmp_path / "ref.exr"))
    assert r.returncode == 2 and "cannot compare a grey image with a colour one" in r.stderr
    assert r.stdout == "", r.stdout
    r = pgi("compare", str(tmp_path / "grey.exr"), str(tmp_path / "grey.exr"), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["mse"] == 0, r.stderr
    # Channels are matched by name: an XYZ image is not compared as if it were RGB.
    xyz = oiio.ImageSpec(64, 64, 3, oiio.FLOAT)
    xyz.channelnames = ("X", "Y", "Z")
    xyz_image = oiio.ImageBuf(xyz)
    xyz_image.set_pixels(
        oiio.ROI(0, 64, 0, 64, 0, 1, 0, 3), rng.uniform(size=(64, 64, 3)).astype("f4")
    )
    xyz_image.write(str(tmp_path / "xyz.exr"))
    r = pgi("compare", str(tmp_path / "xyz.exr"), str(tmp_path / "ref.exr"))
    assert r.returncode == 2 and "expected channels R, G, B" in r.stderr and "X, Y, Z" in r.stderr
    # OpenEXR's uint channels hold integers, which OpenImageIO scaled to [0, 1]: 100 was
    # compared as 2.3e-8 (a review). Integer alpha beside half colour is fine.
    integers = oiio.ImageSpec(64, 64, 3, oiio.UINT)
    _write_oiio(tmp_path / "uint.exr", [integers], [np.full((64, 64, 3), 100)])
    r = pgi("compare", str(tmp_path / "uint.exr"), str(tmp_path / "ref.exr"))
    assert r.returncode == 2 and "R (uint), G (uint), B (uint) hold integers" in r.stderr
    alpha = oiio.ImageSpec(64, 64, 4, oiio.HALF)
    alpha.channelnames = ("R", "G", "B", "A")
    alpha.channelformats = (oiio.HALF, oiio.HALF, oiio.HALF, oiio.UINT)
    _write_oiio(tmp_path / "alpha.exr", [alpha], [np.ones((64, 64, 4))])
    r = pgi("compare", str(tmp_path / "alpha.exr"), str(tmp_path / "alpha.exr"), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["mse"] == 0, r.stderr


def _write_oiio(path: Path, specs: list, images: list[np.ndarray]) -> None:
    """An EXR of one part per spec (a second part makes a multi-part file)."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), specs), out.geterror()
    for k, (spec, image) in enumerate(zip(specs, images, strict=True)):
        if k:
            assert out.open(str(path), spec, "AppendSubimage"), out.geterror()
        assert out.write_image(np.ascontiguousarray(image, dtype=np.float32)), out.geterror()
    out.close()


def test_exr_layouts_the_metrics_cannot_use_are_refused(tmp_path):
    """Channels are matched by name (alpha alone or depth is no grey image; grey with alpha
    is); a multi-part file is not read as its first part; a data window smaller than the
    display window is not compared as if it filled it; a folder is named as one."""
    import OpenImageIO as oiio

    from renderer.imageio import read_exr_and_channels

    def spec(channels: tuple[str, ...], w: int = 8, h: int = 8):
        s = oiio.ImageSpec(w, h, len(channels), oiio.FLOAT)
        s.channelnames = channels
        return s

    ones = np.ones((8, 8, 2))
    _write_oiio(tmp_path / "ya.exr", [spec(("Y", "A"))], [ones * [0.25, 1.0]])
    image, channels = read_exr_and_channels(tmp_path / "ya.exr")
    assert channels == 1 and image.shape == (8, 8, 3) and np.all(image == 0.25)
    for name in ("A", "Z"):
        _write_oiio(tmp_path / f"{name}.exr", [spec((name,))], [ones[..., :1]])
        with pytest.raises(
            PgiError, match=f"expected channels R, G, B or one grey channel Y.*found {name}$"
        ):
            read_exr_and_channels(tmp_path / f"{name}.exr")
    rgb = spec(("R", "G", "B"))
    _write_oiio(tmp_path / "parts.exr", [rgb, rgb], [np.ones((8, 8, 3)), 2 * np.ones((8, 8, 3))])
    with pytest.raises(PgiError, match=r"parts.exr: a multi-part EXR \(2 parts\)"):
        read_exr_and_channels(tmp_path / "parts.exr")
    window = spec(("R", "G", "B"), 6, 5)
    window.x, window.y, window.full_width, window.full_height = 1, 2, 8, 8
    _write_oiio(tmp_path / "window.exr", [window], [np.ones((5, 6, 3))])
    with pytest.raises(PgiError, match="data window .* is not its display window"):
        read_exr_and_channels(tmp_path / "window.exr")
    (tmp_path / "folder.exr").mkdir()
    with pytest.raises(PgiError, match="folder.exr: is a folder, expected an image file"):
        read_exr_and_channels(tmp_path / "folder.exr")


def test_concurrent_failed_reads_give_stderr_back(tmp_path):
    """A failed read captures the process's stderr (OpenEXR prints there itself). Reads from
    several threads at once must each get their own one-line error and leave file
    descriptor 2 where it was: without one capture at a time, a thread restores another's
    capture file as stderr."""
    from concurrent.futures import ThreadPoolExecutor

    from renderer.imageio import read_exr, write_exr

    write_exr(tmp_path / "ref.exr", np.random.default_rng(1).uniform(size=(64, 64, 3)))
    data = (tmp_path / "ref.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    before = os.fstat(2)

    def read_cut(_: int) -> str:
        try:
            read_exr(tmp_path / "cut.exr")
        except PgiError as e:
            return str(e)
        return "read a truncated file"

    with ThreadPoolExecutor(4) as pool:
        errors = list(pool.map(read_cut, range(400)))
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)
    assert all("cannot read pixels" in e and "\n" not in e for e in errors), set(errors)


def test_interrupt_inside_mitsuba_exits_130(monkeypatch, capsys):
    """Mitsuba's JIT turns Ctrl-C into a RuntimeError caused by the KeyboardInterrupt."""
    from renderer import cli

    def interrupted(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as e:
            raise RuntimeError("drjit.custom(): error while calling the forward callback") from e

    monkeypatch.setattr(cli, "cmd_validate", interrupted)
    assert cli.main(["validate", "cbox"]) == 130
    assert "interrupted" in capsys.readouterr().err
    monkeypatch.setattr(cli, "cmd_validate", lambda args: 1 / 0)
    with pytest.raises(ZeroDivisionError):  # a real bug still shows its traceback
        cli.main(["validate", "cbox"])


def test_compare_reports_metrics_as_json(tmp_path):
    from renderer.imageio import write_exr

    rng = np.random.default_rng(0)
    ref = rng.uniform(0.1, 1.0, (8, 8, 3)).astype(np.float32)
    write_exr(tmp_path / "ref.exr", ref)
    write_exr(tmp_path / "test.exr", ref * 1.1)
    r = pgi("compare", str(tmp_path / "test.exr"), str(tmp_path / "ref.exr"), "--json")
    assert r.returncode == 0, r.stderr
    metrics = json.loads(r.stdout)
    assert metrics["mse"] == pytest.approx(np.mean((0.1 * ref.astype(np.float64)) ** 2), rel=1e-5)
    assert {"rmse", "relmse", "relmse_trimmed", "mape", "smape"} <= set(metrics)
    # Below 3x3 pixels SSIM is undefined: null in the JSON (a bare NaN is not JSON)
    write_exr(tmp_path / "ref1.exr", ref[:1, :1])
    write_exr(tmp_path / "test1.exr", ref[:1, :1] * 1.1)
    r = pgi("compare", str(tmp_path / "test1.exr"), str(tmp_path / "ref1.exr"), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["one_minus_ssim"] is None, r.stdout


def test_compare_against_two_references_estimates_their_own_error(tmp_path):
    """Two independent references, each the truth plus noise of variance s^2: the comparison
    is against their mean, whose MSE s^2/2 is estimated as a quarter of theirs to each
    other. A test image no noisier than the references gets the note that the reference
    limits the comparison; one far noisier does not."""
    from renderer.imageio import write_exr

    rng = np.random.default_rng(1)
    truth = rng.uniform(0.5, 1.0, (64, 64, 3))
    s = 0.02
    for name in ("ref_a", "ref_b", "test_close"):
        write_exr(tmp_path / f"{name}.exr", (truth + rng.normal(0, s, truth.shape)).astype("f4"))
    write_exr(tmp_path / "test_far.exr", (truth + rng.normal(0, 20 * s, truth.shape)).astype("f4"))
    refs = [str(tmp_path / "ref_a.exr"), str(tmp_path / "ref_b.exr")]
    r = pgi("compare", str(tmp_path / "test_close.exr"), *refs, "--json")
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)
    # 64x64x3 values: the estimate's relative spread is ~2 %
    assert m["ref_mse"] == pytest.approx(s**2 / 2, rel=0.1)
    assert m["mse"] == pytest.approx(s**2 * 1.5, rel=0.1)  # the test's s^2 plus the mean's
    assert "limits this comparison" in r.stderr
    r = pgi("compare", str(tmp_path / "test_far.exr"), *refs)
    assert r.returncode == 0 and "ref_relmse" in r.stdout and r.stderr == "", r.stderr
    r = pgi("compare", str(tmp_path / "test_far.exr"), refs[0])  # one reference: no estimate
    assert r.returncode == 0 and "ref_relmse" not in r.stdout and r.stderr == ""
    # The workflow's reference (the mean of two halves) brings its error in its sidecar.
    from compare.runs import merge_reference

    merged = tmp_path / "merged.exr"
    merge_reference(*refs, merged, merged.with_suffix(".json"))
    r = pgi("compare", str(tmp_path / "test_close.exr"), str(merged), "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["ref_mse"] == pytest.approx(m["ref_mse"])
    assert "limits this comparison" in r.stderr
    write_exr(tmp_path / "small.exr", truth[:8, :8].astype("f4"))
    r = pgi("compare", str(tmp_path / "test_far.exr"), refs[0], str(tmp_path / "small.exr"))
    assert r.returncode != 0 and "small.exr" in r.stderr and "Traceback" not in r.stderr


def test_a_reference_sidecar_with_impossible_errors_is_ignored(tmp_path):
    """A hand-edited ref.json whose own error is Infinity, NaN, negative or a boolean gives no
    estimate: Infinity used to reach `--json` output and end in a traceback."""
    from renderer.imageio import write_exr

    image = np.full((8, 8, 3), 0.5, np.float32)
    write_exr(tmp_path / "ref.exr", image)
    write_exr(tmp_path / "test.exr", image * 1.1)
    for bad in ("Infinity", "NaN", "-1", "true"):
        sidecar = {"width": 8, "height": 8, "halves_relmse": 1e-3, "halves_mse": 1e-3,
                   "ref_relmse": 1e-3, "ref_mse": 1e-3}  # fmt: skip
        text = json.dumps(sidecar).replace('"ref_relmse": 0.001', f'"ref_relmse": {bad}')
        (tmp_path / "ref.json").write_text(text)
        r = pgi("compare", str(tmp_path / "test.exr"), str(tmp_path / "ref.exr"), "--json")
        assert r.returncode == 0 and "ref_relmse" not in r.stdout, (bad, r.stderr)
    (tmp_path / "ref.json").write_text(json.dumps(sidecar))  # a sound one is read
    r = pgi("compare", str(tmp_path / "test.exr"), str(tmp_path / "ref.exr"), "--json")
    assert json.loads(r.stdout)["ref_relmse"] == 1e-3


def test_unwritable_outputs_are_refused_before_rendering(tmp_path):
    (tmp_path / "out" / "a.json").mkdir(parents=True)  # the sidecar's path is taken
    (tmp_path / "dir.exr").mkdir()
    (tmp_path / "s.t0.5.exr").mkdir()  # a snapshot's path is taken
    for target, expected, more in (
        ("out/a.exr", "a.json is a directory", []),
        ("dir.exr", "is a directory", []),
        ("s.exr", "s.t0.5.exr is a directory", ["--snapshots", "0.5"]),
        # permission bits say yes to root here, yet no file can be made: found by a probe
        ("/proc/pgi.exr", "cannot write in /proc", []),
    ):
        args = ["render", "cbox", "--method", "pt", "--spp", "1", *more, "-o", target]
        r = pgi(*args, cwd=tmp_path)
        assert r.returncode == 2 and expected in r.stderr and "Traceback" not in r.stderr
    names = ["a.json", "dir.exr", "out", "s.t0.5.exr"]
    assert sorted(p.name for p in tmp_path.rglob("*")) == names


def test_a_setting_the_method_does_not_read_is_refused(tmp_path):
    """Mitsuba has no transmittance estimator of ours: `--set integrator.estimator=delta`
    would render plain Mitsuba under another name."""
    out = tmp_path / "m.exr"
    for kv in ("integrator.estimator=delta", "integrator.march_step=0.1", "integrator.rr=mitsuba"):
        r = pgi("render", "smoke", "--method", "mitsuba", "--spp", "1", *small("--set", kv),
                "-o", str(out))  # fmt: skip
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert f"--set {kv}: Mitsuba does not read this setting" in r.stderr, r.stderr
    # The reference is Mitsuba's volpath too.
    r = pgi("reference", "smoke", "--spp", "1", *small("--set", "integrator.estimator=delta"),
            "-o", str(out))  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "integrator.estimator=delta: Mitsuba does not read this setting" in r.stderr
    assert list(tmp_path.iterdir()) == []
    r = pgi("render", "smoke", "--method", "pt", "--spp", "1",
            *small("--set", "integrator.estimator=delta"), "-o", str(out))  # fmt: skip
    assert r.returncode == 0 and out.is_file(), r.stderr


def test_checks_after_loading_name_where_the_value_is_written(tmp_path):
    """Checks made once the scene is loaded (Mitsuba's limits, the ray-marching step against
    the grid) name the file, include or override that wrote the value, as loading's own
    errors do; they once named the main scene file whatever wrote it."""
    out = tmp_path / "r.exr"
    r = pgi("reference", "cbox-fog", "--spp", "1", *small("--set", "media.fog.phase.g=0.9995"),
            "-o", str(out))  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert (
        "(override 'media.fog.phase.g=0.9995'): media.fog.phase.g = 0.9995: Mitsuba's HG"
        in r.stderr
    ), r.stderr
    r = pgi("validate", "cbox-grid", "--set", "integrator.march_step=1e-9")
    assert r.returncode == 2, r.stderr
    assert "(override 'integrator.march_step=1e-9'): integrator.march_step: 1e-09 is below" in (
        r.stderr
    )
    (tmp_path / "media.yaml").write_text(
        "media: {fog: {type: homogeneous, sigma_t: [1, 0, 1], albedo: 0.8}}\n"
    )
    (tmp_path / "scene.yaml").write_text(f"include: [{SCENES / 'cbox' / 'box.yaml'}, media.yaml]\n")
    # the mitsuba method renders the scene as written (a reference would render it grey)
    r = pgi("render", str(tmp_path), "--method", "mitsuba", "--spp", "1",
            *small("--set", "camera.medium=fog", "-o", str(out)))  # fmt: skip
    assert r.returncode == 2, r.stderr
    assert f"{tmp_path / 'media.yaml'}: media.fog.sigma_t = [1.0, 0.0, 1.0]" in r.stderr, r.stderr
    assert not out.exists()


def test_without_threads_both_renderers_take_the_cores_they_may_use(tmp_path):
    """Restricted to one core (as a batch scheduler restricts a job), `pgi render` and
    `pgi reference` (Dr.Jit's default) both run one thread, not one per core of the machine:
    a timed render on more threads than cores would be an unfair comparison."""
    one_core = min(os.sched_getaffinity(0))
    for command in (["render", "cbox", "--method", "pt"], ["reference", "cbox"]):
        out = tmp_path / f"{command[0]}.exr"
        r = subprocess.run(
            [*PGI, *command, "--spp", "1", "-q", *small(), "-o", str(out)],
            capture_output=True,
            text=True,
            timeout=300,
            preexec_fn=lambda: os.sched_setaffinity(0, {one_core}),
        )
        assert r.returncode == 0, r.stderr
        assert json.loads(out.with_suffix(".json").read_text())["threads"] == 1, command


def test_validate_version_reference_and_every_method_succeed(tmp_path):
    """The success paths a user takes first: each writes what it says and exits 0."""
    from renderer.imageio import read_exr
    from renderer.methods import method_ids

    v = pgi("validate", "cbox-fog")
    assert v.returncode == 0 and "cbox-fog" in v.stdout and "ok (" in v.stdout, v.stderr
    assert pgi("--version").stdout.startswith("pgi ")
    ref = tmp_path / "ref.exr"
    r = pgi("reference", "cbox", "--spp", "16", "--check", "1", *small(), "-o", str(ref))
    assert r.returncode == 0, r.stderr
    info = json.loads(ref.with_suffix(".json").read_text())
    assert read_exr(ref).mean() > 0 and info["spp"] == 16
    # checked against a second of pgi's pt: a sound reference passes, in one line
    assert "Mitsuba's reference of cbox passed its checks" in r.stdout.splitlines()
    trust = info["trust"]
    assert trust["trustworthy"] and trust["findings"] == [] and trust["check"]["spp"] > 0
    assert info["threads"] == available_cores()  # without --threads: the cores it may use
    for method in method_ids():
        out = tmp_path / f"{method}.exr"
        r = pgi(
            "render", "cbox", "--method", method, "--time", "0.3", "-q", *small(), "-o", str(out)
        )
        assert r.returncode == 0, (method, r.stderr)
        info = json.loads(out.with_suffix(".json").read_text())
        assert info["method"] == method and info["spp"] > 0
        assert info["render_seconds"] + info["last_iteration_seconds"] / 2 >= 0.3
        assert read_exr(out).mean() > 0, method


def test_spp_budget_is_met_exactly_by_every_method(tmp_path):
    """--spp N stops every method at N samples per pixel (lt: light paths per pixel); an
    iteration size that cannot add up to N is refused before rendering."""
    from renderer.methods import method_ids

    for method in method_ids():
        out = tmp_path / f"{method}.exr"
        r = pgi("render", "cbox", "--method", method, "--spp", "6", "-q", *small(), "-o", str(out))
        assert r.returncode == 0, (method, r.stderr)
        assert json.loads(out.with_suffix(".json").read_text())["spp"] == 6, method
    for method, param in [("pt", "spp_per_wave=4"), ("mitsuba", "spp_per_iteration=4"),
                          ("pm", "spp_per_iteration=4"), ("lt", "light_paths=100")]:  # fmt: skip
        args = ["--spp", "6", "--set", f"method.{param}", *small(), "-o", str(tmp_path / "x.exr")]
        r = pgi("render", "cbox", "--method", method, *args)
        assert r.returncode == 2 and "must divide --spp" in r.stderr, (method, r.stderr)
        assert not (tmp_path / "x.exr").exists()


@pytest.mark.parametrize(
    ("failure", "code", "message"),
    [
        (PgiError("out of photons"), 2, "pgi: error: out of photons"),
        (KeyboardInterrupt(), 130, "pgi: interrupted"),
        ("terminated", 143, "pgi: terminated"),
    ],
)
def test_failure_mid_render_keeps_whole_snapshots_only(
    tmp_path, monkeypatch, capsys, failure, code, message
):
    """A render that fails or is interrupted after a snapshot: the snapshot stays whole (image
    and sidecar), no final image or sidecar is written, and the user gets one line (plus a
    note naming what was kept), no traceback."""
    from renderer import cli
    from renderer.imageio import read_exr
    from renderer.methods.pt import PathTracing

    run = PathTracing.run_iteration
    if failure == "terminated":
        failure = cli.Terminated()  # what the CLI's SIGTERM handler raises

    def failing(self, iteration):
        if iteration >= 1:
            raise failure
        run(self, iteration)

    monkeypatch.setattr(PathTracing, "run_iteration", failing)
    out = tmp_path / "fog.exr"
    args = [
        "render",
        "cbox-fog",
        "--method",
        "pt",
        "--snapshots",
        "0.000001,60",
        "-q",
        "-o",
        str(out),
    ]
    assert cli.main([*args, *small("--threads", "1")]) == code
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    snapshot = tmp_path / "fog.t1e-06.exr"
    assert f"kept {snapshot}" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fog.t1e-06.exr", "fog.t1e-06.json"]
    sidecar = json.loads(snapshot.with_suffix(".json").read_text())
    assert sidecar["snapshot_budget"] == 1e-06 and sidecar["spp"] > 0
    assert read_exr(snapshot).shape == (16, 16, 3)
    # A final image and a snapshot left by an earlier run are named as such, not taken for
    # this run's.
    out.write_bytes(b"earlier")
    (tmp_path / "fog.t60.exr").write_bytes(b"earlier")
    assert cli.main([*args, *small("--threads", "1")]) == code
    assert f"{tmp_path / 'fog.t60.exr'}, {out} are from an earlier run" in capsys.readouterr().err
    assert out.read_bytes() == b"earlier"


def test_render_refuses_hostile_scene_files_before_looking_for_its_inputs(tmp_path):
    """`pgi render` walks the scene's documents for the files it reads (so as not to overwrite
    them) before validating them: a recursive YAML alias, a "billion laughs" and a symlink
    loop used to give a RecursionError, a hang and a RuntimeError there."""
    box = SCENES / "cbox" / "box.yaml"
    (tmp_path / "recursive.yaml").write_text(f"include: {box}\nstresses: &a [*a]\n")
    laughs = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    laughs += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    (tmp_path / "laughs.yaml").write_text(f"include: {box}\n" + "\n".join(laughs) + "\n")
    (tmp_path / "loop.ply").symlink_to(tmp_path / "loop.ply")
    looped = {"include": str(box),
              "shapes": [{"type": "mesh", "file": "loop.ply", "material": "white"}]}  # fmt: skip
    (tmp_path / "symlink.yaml").write_text(yaml.safe_dump(looped))
    for name, expected in (("recursive", "stresses: expected a list of strings"),
                           ("laughs", "a0: unknown key"),
                           ("symlink", "file: mesh file is a symbolic link")):  # fmt: skip
        r = pgi("render", str(tmp_path / f"{name}.yaml"), "--method", "pt", "--spp", "1",
                "-o", str(tmp_path / "x.exr"))  # fmt: skip
        assert r.returncode == 2 and "Traceback" not in r.stderr, (name, r.stderr)
        assert expected in r.stderr and len(r.stderr.splitlines()) == 1, (name, r.stderr)
    long_name = tmp_path / ("a" * 300 + ".exr")
    r = pgi("render", "cbox", "--method", "pt", "--spp", "1", "-o", str(long_name))
    assert r.returncode == 2 and r.stderr.strip().endswith(": File name too long"), r.stderr
    # 250 bytes pass the file system, but not the image's temporary name (a traceback after
    # the render, before)
    r = pgi(
        "render", "cbox", "--method", "pt", "--spp", "1", "-o", str(tmp_path / ("a" * 246 + ".exr"))
    )
    assert r.returncode == 2 and "file name too long (at most 239 bytes)" in r.stderr, r.stderr
    # an input file's name too long for the file system: Path.is_file raised
    looped["shapes"][0]["file"] = "b" * 300 + ".ply"
    (tmp_path / "long.yaml").write_text(yaml.safe_dump(looped))
    for command in ("validate", "render"):
        extra = (
            ["--method", "pt", "--spp", "1", "-o", str(tmp_path / "y.exr")]
            if command == "render"
            else []
        )
        r = pgi(command, str(tmp_path / "long.yaml"), *extra)
        assert r.returncode == 2 and r.stderr.strip().endswith("file name too long"), r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    # None of these runs wrote an image, a sidecar or a temporary file.
    assert not [p.name for p in tmp_path.iterdir() if p.suffix in (".exr", ".json", ".tmp")]


def test_progress_lines(monkeypatch, capsys):
    """On a terminal, a message after the bar starts a line of its own; otherwise the last
    plain line is not printed twice when the final update repeats it."""
    from renderer import cli
    from renderer.progressive import Progress

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    Progress(None, 10, enabled=True).update(1.0, 5)
    assert cli._interrupted(KeyboardInterrupt()) == 130
    assert capsys.readouterr().err.endswith("5 spp\npgi: interrupted\n")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    bar = Progress(None, 10, enabled=True)
    bar.update(6.0, 10)
    bar.update(6.0, 10, force=True)
    assert capsys.readouterr().err == "progress 100.0% 6.0 s 10 spp\n"
    # a render that stops at the iteration end nearest its budget, a little short of it
    Progress(2.0, None, enabled=True).update(1.9, 7, force=True, finished=True)
    assert capsys.readouterr().err == "progress 100.0% 1.9 s 7 spp\n"


def test_ctrl_c_during_start_up_imports_is_one_line():
    """Ctrl-C while a command still imports its modules: the interrupt handler must not
    import them again (it used to, for the progress bar, and raised from the broken
    import instead). Here every import of yaml is interrupted."""
    code = (
        "import sys\n"
        "class Interrupt:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'yaml':\n"
        "            raise KeyboardInterrupt\n"
        "sys.meta_path.insert(0, Interrupt())\n"
        "from renderer.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code, "validate", "cbox"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 130 and r.stderr == "pgi: interrupted\n", r.stderr


class _ClockedMethod:
    """A method whose iterations take set lengths on a clock the test controls."""

    clock = [0.0]
    lengths = [0.7, 0.6, 0.6, 0.6, 0.6]

    def __init__(self, scene, *, seed, threads, params, spp_budget=None) -> None:
        self.iterations = 0
        self.method_params = {}

    def run_iteration(self, iteration: int) -> None:
        self.clock[0] += self.lengths[iteration]
        self.iterations += 1

    def image(self) -> np.ndarray:
        return np.full((4, 4, 3), float(self.iterations))

    def stats(self) -> dict:
        return {"iterations": self.iterations, "spp": self.iterations, "nonfinite": 0}


def test_budgets_end_at_the_nearest_iteration_end(tmp_path, monkeypatch):
    """With iterations of 0.7, 0.6, 0.6 ... s, the 1 s snapshot is the image at 0.7 s (1.3 s
    lies further away), the 1.5 s one the image at 1.3 s, and a 2 s budget ends at 1.9 s;
    always taking the first iteration end past a time would give 1.3, 1.9 and 2.5 s."""
    import types

    from conftest import load_small
    from renderer import progressive

    _ClockedMethod.clock[0] = 0.0
    monkeypatch.setattr(progressive, "get_method", lambda _: _ClockedMethod)
    monkeypatch.setattr(
        progressive, "time", types.SimpleNamespace(perf_counter=lambda: _ClockedMethod.clock[0])
    )
    settings = progressive.RenderSettings(
        method="pt", threads=1, time_budget=2.0, snapshots=(1.0, 1.5)
    )
    out = tmp_path / "a.exr"
    final = progressive.render(load_small("cbox", 4, 4), settings, out, progress=False)
    seen = {
        label: json.loads(progressive.snapshot_path(out, label).with_suffix(".json").read_text())
        for label in (1.0, 1.5)
    }
    assert [seen[1.0]["iterations"], seen[1.5]["iterations"], final["iterations"]] == [1, 2, 3]
    assert final["render_seconds"] == pytest.approx(1.9)
    assert final["last_iteration_seconds"] == pytest.approx(0.6)
    # the benchmarks' timed runs follow the same rule
    _ClockedMethod.clock[0] = 0.0
    method = _ClockedMethod(None, seed=0, threads=1, params={})
    assert progressive.run_for(method, 2.0) == pytest.approx(1.9) and method.iterations == 3
    _ClockedMethod.clock[0] = 0.0
    method = _ClockedMethod(None, seed=0, threads=1, params={})
    got = list(progressive.iterate_to(method, [1.5, 1.0, 2.0]))
    assert got == [(1.0, 0.7), (1.5, pytest.approx(1.3)), (2.0, pytest.approx(1.9))]
    # ...and by another clock when given one (the benchmarks' CPU seconds): half as fast here
    _ClockedMethod.clock[0] = 0.0
    method = _ClockedMethod(None, seed=0, threads=1, params={})
    got = list(progressive.iterate_to(method, [0.95], clock=lambda: 0.5 * _ClockedMethod.clock[0]))
    assert got == [(0.95, pytest.approx(0.95))] and method.iterations == 3


def test_a_failed_final_write_names_the_snapshots_it_kept(tmp_path, monkeypatch, capsys):
    """The final image cannot be written (a full disk): the snapshots written before stay, and
    the note says so, as after a failure mid-render (it once said nothing of them)."""
    from renderer import cli, progressive
    from renderer.errors import PgiError

    write = progressive.write_image_and_sidecar
    out = tmp_path / "fog.exr"

    def full_disk(path, image, info):
        if path == out:
            raise PgiError(f"{out.with_suffix('.json')}: cannot write: No space left on device")
        write(path, image, info)

    monkeypatch.setattr(progressive, "write_image_and_sidecar", full_disk)
    args = ["render", "cbox-fog", "--method", "pt", "--spp", "2", "--snapshots", "0.000001",
            "-q", "-o", str(out)]  # fmt: skip
    assert cli.main([*args, *small("--threads", "1")]) == 2
    err = capsys.readouterr().err
    assert f"note: no final image; kept {tmp_path / 'fog.t1e-06.exr'}" in err, err
    assert "No space left on device" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fog.t1e-06.exr", "fog.t1e-06.json"]


def test_names_no_file_can_have_get_one_line(tmp_path):
    """File names the system cannot look up: a NUL character in a scene's file name (render,
    reference, validate), a name too long for the file system (compare), and an output that
    is a symbolic link looping back on itself (replaced by the image, as any output link is).
    Each once ended in a traceback where the check against overwriting the scene's own files
    followed links."""
    nul = ("--set", 'shapes[0]={type: mesh, file: "a\\0b.obj", material: white}')
    out = tmp_path / "n.exr"
    for args in (["render", "cbox", "--method", "pt", "--spp", "1", *small(*nul), "-o", str(out)],
                 ["reference", "cbox", "--spp", "1", *small(*nul), "-o", str(out)],
                 ["validate", "cbox", *nul]):  # fmt: skip
        r = pgi(*args)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "shapes[0].file: mesh file cannot exist: its name has a NUL character" in r.stderr
        assert "\0" not in r.stderr and "a\\x00b.obj" in r.stderr, r.stderr  # shown escaped
    (tmp_path / "l1").symlink_to("l2")
    (tmp_path / "l2").symlink_to("l1")
    loop = tmp_path / "loop.exr"
    loop.symlink_to("l2")
    r = pgi("render", "cbox", "--method", "pt", "--spp", "1", *small("-q", "-o", str(loop)))
    assert r.returncode == 0 and loop.is_file() and not loop.is_symlink(), r.stderr
    for pair in (["a" * 300 + ".exr", str(loop)], [str(loop), "a" * 300 + ".exr"]):
        r = pgi("compare", *pair)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "File name too long" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l1", "l2", "loop.exr", "loop.json"]


def test_a_failed_pair_write_leaves_the_earlier_pair_as_it_was(tmp_path, monkeypatch):
    """An image and its sidecar rewritten at the same path: when either write fails (a full
    disk), the earlier image and sidecar stay as they were and no temporary file is left. The
    image was once moved into place before the sidecar was written, so a failed sidecar left
    the earlier sidecar beside no image."""
    from pathlib import Path

    from renderer import imageio
    from renderer.errors import PgiError

    out = tmp_path / "a.exr"
    first = np.full((2, 3, 3), 0.25)
    imageio.write_image_and_sidecar(out, first, {"run": 1})
    original_write_text = Path.write_text

    def full_disk(self, *args, **kwargs):
        raise OSError(28, "No space left on device")

    for failing in ("sidecar", "image"):
        with monkeypatch.context() as m:
            if failing == "sidecar":
                m.setattr(Path, "write_text", full_disk)
            else:
                m.setattr(imageio.oiio.ImageOutput, "create", staticmethod(lambda name: None))
            with pytest.raises(PgiError, match="No space left|cannot create image writer"):
                imageio.write_image_and_sidecar(out, first * 2, {"run": 2})
        assert Path.write_text is original_write_text
        assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr", "a.json"], failing
        assert np.array_equal(imageio.read_exr(out), first) and imageio.read_json(
            out.with_suffix(".json")
        ) == {"run": 1}, failing
    real_replace = imageio.os.replace

    def replace_only_images(src, dst):  # a rename that fails for everything but an .exr
        if not str(dst).endswith(".exr"):
            raise OSError(5, "Input/output error")
        real_replace(src, dst)

    def replace_nothing(src, dst):
        raise OSError(5, "Input/output error")

    with monkeypatch.context() as m:
        m.setattr(imageio.os, "replace", replace_only_images)
        with pytest.raises(PgiError, match="Input/output error"):  # the image moved, then the
            imageio.write_image_and_sidecar(out, first * 2, {"run": 2})  # sidecar failed:
        assert list(tmp_path.iterdir()) == []  # neither is left
        imageio.write_exr(out, first)
        with pytest.raises(PgiError, match="Input/output error"):
            imageio.write_json(out.with_suffix(".json"), {"run": 1})
        assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]  # a lone file is kept
        m.setattr(imageio.os, "replace", replace_nothing)
        with pytest.raises(PgiError, match="Input/output error"):
            imageio.write_exr(out, first * 3)
        assert np.array_equal(imageio.read_exr(out), first)  # a first failure changes nothing
    imageio.write_image_and_sidecar(out, first * 2, {"run": 2})  # and a good write replaces both
    assert np.array_equal(imageio.read_exr(out), first * 2)
    assert imageio.read_json(out.with_suffix(".json")) == {"run": 2}


@pytest.mark.parametrize("threads", ["1", "2"])  # 2: pt's lanes trace on two threads
def test_sigterm_mid_render_cleans_up_as_ctrl_c_does(tmp_path, threads):
    """SIGTERM (a cancelled workflow job, `timeout`) ends a render as Ctrl-C does: the
    finished snapshot stays whole, no final image and no temporary file are left, one line
    says so, and the exit status is 128 + 15."""
    import signal
    import time

    out = tmp_path / "fog.exr"
    args = ["render", "cbox-fog", "--method", "pt", "--time", "60", "--snapshots", "0.5",
            *small("--threads", threads), "-o", str(out)]  # fmt: skip
    proc = subprocess.Popen(
        [*PGI, *args], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    snapshot = tmp_path / "fog.t0.5.json"
    deadline = time.monotonic() + 300
    while not snapshot.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert snapshot.exists(), proc.communicate()
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    assert stderr.strip().splitlines()[-1] == "pgi: terminated" and "Traceback" not in stderr
    assert f"kept {tmp_path / 'fog.t0.5.exr'}" in stderr and stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fog.t0.5.exr", "fog.t0.5.json"]


def test_sigterm_whose_exception_was_lost_still_ends_as_terminated(capsys):
    """The SIGTERM handler's exception can be lost on its way (where is not known); the plain
    KeyboardInterrupt a native pass raises next must still end as SIGTERM does (143), not as
    Ctrl-C (130): one run in 30 of the test above did, under load."""
    import signal

    from renderer import cli

    previous = signal.getsignal(signal.SIGTERM)
    try:
        assert cli._interrupted(KeyboardInterrupt()) == 130  # no SIGTERM yet: Ctrl-C
        try:
            cli._terminate(signal.SIGTERM, None)
        except cli.Terminated:
            pass  # dropped, as happened under load
        assert cli._interrupted(KeyboardInterrupt()) == 143
        assert capsys.readouterr().err.splitlines()[-1] == "pgi: terminated"
    finally:
        signal.signal(signal.SIGTERM, previous)
        cli._sigterm_arrived.clear()


def test_a_signal_ends_a_pass_through_dense_media_at_once(tmp_path):
    """One voxel of optical depth ~10^4: every tentative collision of pm's 65536 photons
    through the box costs a lookup, and its first pass runs for minutes without returning to
    Python, whose handlers then never ran: SIGTERM waited over three minutes (a review). Now
    the signal stops media tracking and the render ends as after Ctrl-C."""
    import os
    import signal
    import time

    density = np.zeros((8, 8, 8), np.float32)
    density[3, 3, 3] = 1
    np.save(tmp_path / "one-voxel.npy", density)
    out = tmp_path / "dense.exr"
    args = ["render", "cbox-grid", "--method", "pm", "--time", "1", "-q",
            "--set", f"media.smoke.density={tmp_path / 'one-voxel.npy'}",
            "--set", "media.smoke.sigma_t=40000", *small("--threads", "1"),
            "-o", str(out)]  # fmt: skip
    proc = subprocess.Popen(
        [*PGI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )

    def cpu_seconds() -> float:  # user + system time of the render so far
        fields = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    deadline = time.monotonic() + 120
    # loading takes about a second of CPU: past three, the photon pass runs
    while proc.poll() is None and cpu_seconds() < 3 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    try:
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 143 and stderr.strip().splitlines()[-1] == "pgi: terminated", stderr
    assert not out.exists()


def test_standard_output_that_cannot_be_written(tmp_path):
    """A reader that closes the pipe (`pgi methods | head -0`) ends pgi quietly with SIGPIPE's
    status; a full disk is one line on stderr. Neither is a traceback."""
    proc = subprocess.Popen([*PGI, "methods"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    proc.stdout.close()  # before pgi writes
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and stderr == ""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here: the full-stdout half is not run")
    with open("/dev/full", "w") as full:
        r = subprocess.run([*PGI, "methods"], stdout=full,
                           stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert r.returncode == 2, r.stderr
    assert r.stderr == "pgi: error: cannot write to standard output: No space left on device\n"


def test_standard_output_closed_from_the_start(tmp_path):
    """Started with stdout closed (`pgi ... >&-`, so Python has none): what pgi would print is
    lost, the work is done and the exit is 0, without a traceback."""

    def closed(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([*PGI, *args], stderr=subprocess.PIPE, text=True,
                              preexec_fn=lambda: os.close(1))  # fmt: skip

    r = closed("methods")
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    out = tmp_path / "x.exr"
    r = closed("render", "cbox", "--method", "pt", "--spp", "1", "-q", "--threads", "1",
               "--set", "film.width=8", "--set", "film.height=8", "-o", str(out))  # fmt: skip
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert out.exists() and out.with_suffix(".json").exists()


def test_fingerprints_cover_the_code_each_output_runs():
    """Render code: every renderer source, C++ included. Reference code: the scene loader
    and the Mitsuba export, not the methods or the C++ core. Both are content hashes."""
    from renderer import fingerprint

    render = {p.relative_to(fingerprint.PACKAGE).as_posix() for p in fingerprint.render_sources()}
    assert {"methods/pt.py", "cpp/pt.cpp", "cpp/medium.h", "scene/mitsuba_export.py"} <= render
    reference = {
        p.relative_to(fingerprint.PACKAGE).as_posix() for p in fingerprint.reference_sources()
    }
    assert {"reference.py", "scene/loader.py", "scene/mitsuba_export.py", "volumes.py"} <= reference
    assert not any(p.startswith(("methods/", "cpp/")) for p in reference)
    r = pgi("fingerprint")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == fingerprint.fingerprints()


def test_fingerprint_refuses_a_core_older_than_its_sources(tmp_path):
    """An edited C++ source not yet built: the workflow would record its digest for renders
    that ran the old binary."""
    import os

    from renderer import fingerprint

    core, source = tmp_path / "_core.so", fingerprint.PACKAGE / "cpp" / "pt.cpp"
    core.write_bytes(b"")
    os.utime(core, (source.stat().st_mtime + 10,) * 2)
    fingerprint.check_core_is_current(core, [source])  # built after the source: fine
    os.utime(core, (source.stat().st_mtime - 10,) * 2)
    with pytest.raises(PgiError, match=r"renderer/cpp/pt.cpp is newer than the built C\+\+ core"):
        fingerprint.check_core_is_current(core, [source])


def test_a_render_of_a_stale_core_says_its_code_is_unknown(monkeypatch):
    """A render still runs when a C++ source is newer than the core, but its sidecar's
    `code` does not claim the sources' digest."""
    from renderer import progressive

    def stale():
        raise PgiError("renderer/cpp/pt.cpp is newer than the built C++ core")

    monkeypatch.setattr(progressive, "render_fingerprint", stale)
    assert progressive._code_fingerprint() == (
        "unknown: renderer/cpp/pt.cpp is newer than the built C++ core"
    )


def test_fingerprints_follow_the_mitsuba_variant(monkeypatch):
    """Mitsuba's llvm and scalar variants draw different random streams: switching reruns
    the references and Mitsuba's renders (the workflow once kept them)."""
    from renderer import fingerprint

    monkeypatch.setenv("PGI_MITSUBA_VARIANT", "scalar_rgb")
    scalar = fingerprint.fingerprints()
    monkeypatch.setenv("PGI_MITSUBA_VARIANT", "llvm_ad_rgb")
    llvm = fingerprint.fingerprints()
    assert scalar["reference"] != llvm["reference"] and scalar["render"] != llvm["render"]


def test_outputs_never_overwrite_a_file_the_scene_reads(tmp_path):
    """`-o scene.exr` next to a scene file `scene.json` would have replaced it by the sidecar."""
    scene = tmp_path / "shot.json"
    scene.write_text(json.dumps(yaml.safe_load((SCENES / "cbox" / "scene.yaml").read_text())
                                | {"include": [str(SCENES / "cbox" / "box.yaml")]}))  # fmt: skip
    before = scene.read_bytes()
    for args in (["render", str(scene), "--method", "pt", "--spp", "1"],
                 ["reference", str(scene), "--spp", "1"]):  # fmt: skip
        r = pgi(*args, *small(), "-o", str(tmp_path / "shot.exr"))
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "which the scene reads" in r.stderr, r.stderr
    assert scene.read_bytes() == before and not (tmp_path / "shot.exr").exists()


def test_outputs_never_overwrite_a_file_an_override_names(tmp_path):
    """A phase table named only by --set is read by the scene too: `-o phase.exr` beside
    `phase.json` would have replaced the table by the sidecar, with exit 0."""
    for name in ("cbox", "cbox-fog"):  # cbox-fog includes ../cbox/box.yaml
        shutil.copytree(SCENES / name, tmp_path / name)
    table = tmp_path / "cbox-fog" / "phase.json"
    table.write_text("[1, 2, 3]")
    phase = "media.fog.phase={type: tabulated, file: phase.json}"
    fog = tmp_path / "cbox-fog"
    for args in (["render", str(fog), "--method", "pt", "--spp", "1"],
                 ["reference", str(fog), "--spp", "1"]):  # fmt: skip
        r = pgi(*args, *small(), "--set", phase, "-o", str(fog / "phase.exr"))
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "which the scene reads" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    assert table.read_text() == "[1, 2, 3]" and not (fog / "phase.exr").exists()


def test_radiance_beyond_float32_is_a_clear_error(tmp_path):
    """A scene within every limit can still be too bright for a float EXR (a point light of
    intensity 1e30 a hair from a wall): that is the user's, not a bug; nothing is written."""
    from renderer.imageio import write_exr

    out = tmp_path / "hot.exr"
    image = np.ones((2, 2, 3))
    image[0, 0] = 1e44
    with pytest.raises(PgiError, match=r"reach 1e\+44, beyond what a float EXR holds"):
        write_exr(out, image)
    assert list(tmp_path.iterdir()) == []
    image[0, 0] = np.nan  # a method's bug, not the scene's: not a user error
    with pytest.raises(ValueError, match="non-finite"):
        write_exr(out, image)


def test_an_unread_setting_is_refused_in_any_spelling(tmp_path):
    out = tmp_path / "m.exr"
    for kv in ("integrator.estimator =delta", "integrator={estimator: delta}"):
        r = pgi("render", "smoke", "--method", "mitsuba", "--spp", "1", *small("--set", kv),
                "-o", str(out))  # fmt: skip
        assert r.returncode == 2 and "does not read this setting" in r.stderr, r.stderr
    assert not out.exists()


def test_dropped_beams_are_said_not_only_recorded(tmp_path):
    """ppb with room for one beam drops nearly all: the image is biased dark, and the
    render says so on stderr, not only in the sidecar."""
    out = tmp_path / "b.exr"
    r = pgi("render", "cbox-fog", "--method", "ppb", "--spp", "1", "--set",
            "method.max_beams=1", "-q", *small(), "-o", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    dropped = json.loads(out.with_suffix(".json").read_text())["beams_truncated"]
    assert dropped > 0 and f"note: {dropped:,} beams beyond method.max_beams" in r.stderr


def test_expected_slopes_have_no_negative_zero():
    from renderer.methods.schedules import expected_mse_slopes

    slopes = expected_mse_slopes([(1.0, 2)])  # alpha 1: the radius never shrinks, slope 0
    assert json.dumps(slopes) == '{"expected_mse_slope": 0.0, "expected_mse_slope_at_edges": 0.0}'


# ---------------------------------------------------------------- references in passes, stored


def test_passes_combine_as_one_mean_with_the_variance_of_their_spread(tmp_path):
    """An accumulation of passes of unequal sizes is their sample-weighted mean; the spread
    of the passes estimates the variance of that mean (unbiased: over many accumulations of
    passes of per-sample variance s^2, the estimate's mean is s^2 / spp). Stored and loaded
    it is the same; a store made with another key is not extended but replaced."""
    from renderer.reference import Accumulation

    rng = np.random.default_rng(3)
    sizes = [4, 4, 8, 16, 1]
    estimates, means = [], []
    for _ in range(400):
        acc = Accumulation.empty(2, 3)
        passes = [1.0 + rng.standard_normal((2, 3, 3)) / np.sqrt(n) for n in sizes]
        for n, image in zip(sizes, passes, strict=True):
            acc.add(image, n, seconds=0.1 * n)
        means.append(acc.mean)
        estimates.append(acc.variance_of_mean())
    want = sum(n * p for n, p in zip(sizes, passes, strict=True)) / sum(sizes)
    np.testing.assert_allclose(acc.mean, want, rtol=1e-12)
    assert acc.spp == 33 and acc.passes == 5
    assert np.mean(estimates) == pytest.approx(1 / 33, rel=0.05)
    assert np.var(means, axis=0).mean() == pytest.approx(1 / 33, rel=0.1)
    assert acc.seconds_per_spp() == pytest.approx(0.1)
    acc.key = {"scene": "x"}
    acc.save(tmp_path / "store.npz")
    back = Accumulation.load(tmp_path / "store.npz", {"scene": "x"}, (2, 3))
    np.testing.assert_array_equal(back.mean, acc.mean)
    assert (back.spp, back.passes, back.pass_log) == (acc.spp, acc.passes, acc.pass_log)
    other = Accumulation.load(tmp_path / "store.npz", {"scene": "y"}, (2, 3))
    assert other.spp == 0 and not other.mean.any()
    assert Accumulation.load(tmp_path / "store.npz", {"scene": "x"}, (3, 3)).spp == 0


def test_image_mean_variance_comes_from_the_passes_image_means(tmp_path):
    """Where a pass's pixels are correlated (bdpt's light paths splat across the image) the
    variance of the image mean is not the pixels' summed: the accumulation estimates it from
    the spread of the passes' image means. Passes whose pixels share one noise term: the
    summed pixel variances underestimate the image mean's variance six-fold (six pixels), the
    passes' image means get it right; it is stored and loaded with the rest."""
    from renderer.reference import Accumulation

    rng = np.random.default_rng(5)
    sizes = [2, 2, 4, 8, 8, 1]
    image_means, estimates, pixel_sums = [], [], []
    for _ in range(400):
        acc = Accumulation.empty(2, 3)
        for n in sizes:  # one noise for every pixel of the pass: per-sample variance 1
            acc.add(np.full((2, 3, 3), 1.0 + rng.standard_normal() / np.sqrt(n)), n, 0.1)
        image_means.append(acc.mean.mean())
        estimates.append(acc.image_mean_variance().mean())
        pixel_sums.append(acc.variance_of_mean().reshape(-1, 3).sum(axis=0).mean() / 36)
    spp = sum(sizes)
    assert np.var(image_means) == pytest.approx(1 / spp, rel=0.15)
    assert np.mean(estimates) == pytest.approx(1 / spp, rel=0.1)
    assert np.mean(pixel_sums) == pytest.approx(1 / (6 * spp), rel=0.1)
    acc.save(tmp_path / "store.npz")
    back = Accumulation.load(tmp_path / "store.npz", {}, (2, 3))
    np.testing.assert_array_equal(back.image_mean_variance(), acc.image_mean_variance())


def test_a_pgi_reference_method_is_pt_or_bdpt_and_only_for_pgi(tmp_path):
    """`pgi reference --method` picks which of pgi's unbiased methods renders a `--source pgi`
    reference; Mitsuba has none, and a biased method is not offered."""
    r = pgi("reference", "cbox", "--method", "bdpt", "--spp", "4", "-o", str(tmp_path / "a.exr"))
    assert r.returncode == 2 and "only a reference of --source pgi has a method" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "a.exr").exists()
    r = pgi(
        "reference", "cbox", "--source", "pgi", "--method", "sppm", "--spp", "4",
        "-o", str(tmp_path / "b.exr"),
    )  # fmt: skip
    assert r.returncode == 2 and "invalid choice: 'sppm'" in r.stderr


def test_a_pgi_reference_is_cross_checked_by_bdpt(tmp_path):
    """`pgi reference --source pgi --check S`: pt's reference is judged against S seconds of
    pgi's bdpt (its pixels correlated within a pass: the image mean's variance from its passes),
    and the sidecar says so; the same scene, rendered alike, passes."""
    out = tmp_path / "ref.exr"
    r = pgi(
        "reference", "cbox", "--source", "pgi", "--spp", "16", "--check", "0.5",
        "--threads", "1", *small(), "-q", "-o", str(out),
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    info = json.loads(out.with_suffix(".json").read_text())
    trust = info["trust"]
    assert trust["checked_against"] == "pgi's bdpt"
    assert trust["reference"] == "pgi's pt reference of cbox"
    assert trust["check"]["renderer"].endswith(" bdpt")
    assert trust["check"]["spp"] > 0 and trust["trustworthy"], trust["line"]


def test_reference_store_is_extended_not_rendered_again(tmp_path):
    """`pgi reference --store`: 16 spp in 8 passes, then 40 from the same store renders the
    24 missing ones only (passes with seeds of their own, continuing the first 8) and the
    image is the weighted mean of both; asking for fewer than the store holds renders none
    and gives all 40. Another seed, or another override, starts a store afresh. The variance
    of the mean is written beside the image."""
    from renderer.imageio import read_exr

    store = str(tmp_path / "store.npz")

    def reference(spp: int, name: str, *extra: str) -> dict:
        out = tmp_path / f"{name}.exr"
        args = ["reference", "cbox", "--spp", str(spp), "--threads", "1", "--store", store]
        args += ["--check", "0"]
        r = pgi(*args, *small(*extra), "-q", "-o", str(out))
        assert r.returncode == 0, r.stderr
        return json.loads(out.with_suffix(".json").read_text())

    first = reference(16, "a")
    assert (first["spp"], first["passes"], first["spp_resumed"]) == (16, 8, 0)
    assert first["variance"] == "a.var.exr" and (tmp_path / "a.var.exr").is_file()
    more = reference(40, "b")
    assert (more["spp"], more["passes"], more["spp_resumed"]) == (40, 16, 16)
    new = reference(24, "c", "--seed", "9")  # another seed: b's passes are not its own
    assert (new["spp"], new["spp_resumed"]) == (24, 0)
    again = reference(16, "d", "--seed", "0")  # and the store now holds seed 9's
    assert again["spp_resumed"] == 0
    from renderer.cli import PGI_REFERENCE_METHODS, SOURCE_NAMES
    from renderer.reference import SOURCES, UNBIASED_METHODS

    assert set(SOURCE_NAMES) == set(SOURCES)  # `--source` offers what there is
    assert PGI_REFERENCE_METHODS == UNBIASED_METHODS  # and `--method`
    reference(40, "e")
    fewer = reference(20, "f")
    assert (fewer["spp"], fewer["spp_resumed"], fewer["render_seconds"] < 0.5) == (40, 40, True)
    np.testing.assert_allclose(read_exr(tmp_path / "f.exr"), read_exr(tmp_path / "e.exr"))
    np.testing.assert_allclose(read_exr(tmp_path / "e.exr"), read_exr(tmp_path / "b.exr"))
    a, b = read_exr(tmp_path / "a.exr"), read_exr(tmp_path / "b.exr")
    assert not np.allclose(a, b)
    assert reference(16, "g", "--set", "integrator.max_depth=3")["spp_resumed"] == 0
