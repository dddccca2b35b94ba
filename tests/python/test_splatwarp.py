"""The `import splatwarp` module against the CLI: every expected value comes from the CLI's own
outputs (files, stderr, --json) on the same inputs, never written down here.
CTest sets PYTHONPATH (build/python), SPLATWARP_CLI and SPLATWARP_SOURCE."""
import gc
import json
import os
import re
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

import splatwarp

ROOT = Path(os.environ.get("SPLATWARP_SOURCE", Path(__file__).resolve().parents[2]))
CLI = os.environ.get("SPLATWARP_CLI", str(ROOT / "build" / "tools" / "splatwarp"))
BEND = ROOT / "samples" / "specs" / "bend.json"
# Small enough for a 2-core machine; the same flags go to the CLI and the module.
FAST = {"iterations": 10, "cells": 16, "eval_points": 2000}


def cli(*args, ok=True):
    run = subprocess.run([CLI, "-q", *map(str, args)], capture_output=True, text=True)
    if ok:
        assert run.returncode == 0, run.stderr
    return run


def flags(settings):
    out = []
    for key, value in settings.items():
        out += ["--" + key.replace("_", "-")] + ([] if value is True else [str(value)])
    return out


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("splatwarp")


@pytest.fixture(scope="session")
def stripes(work):
    path = work / "stripes.ply"
    cli("sample", "stripes", "--count", 2000, "-o", path)
    return path


@pytest.fixture(scope="session")
def cli_deform(work, stripes):
    out = work / "cli-bend"
    cli("deform", stripes, "--spec", BEND, "-o", out, *flags(FAST))
    return out


def read_png(path):
    """The 8-bit RGB(A) pixels of a non-interlaced PNG (what libpng's simplified writer makes)."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and colour in (2, 6) and interlace == 0
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    channels = 3 if colour == 2 else 4
    raw, stride = zlib.decompress(idat), width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b, c = prev[i], prev[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return np.frombuffer(b"".join(rows), np.uint8).reshape(height, width, channels)


def cli_error(run):
    """The message after 'splatwarp: error: ' on the CLI's stderr."""
    assert run.returncode == 1, run.stderr
    line = run.stderr.strip().splitlines()[-1]
    assert line.startswith("splatwarp: error: "), line
    return line[len("splatwarp: error: "):]


def test_read_gives_the_arrays_of_the_file(stripes):
    model = splatwarp.read(stripes)
    info = json.loads(cli("info", stripes, "--json").stdout)
    assert len(model) == info["count"] and model.sh_degree == info["shDegree"]
    k = (model.sh_degree + 1) ** 2
    assert model.positions.shape == (len(model), 3) and model.positions.dtype == np.float32
    assert model.rotations.shape == (len(model), 4) and model.opacities.shape == (len(model),)
    assert model.sh.shape == (len(model), k, 3) and model.sh_rest.shape == (len(model), k - 1, 3)
    np.testing.assert_array_equal(model.sh_dc, model.sh[:, 0, :])
    lo, hi = model.positions.min(axis=0), model.positions.max(axis=0)
    np.testing.assert_allclose(lo, info["bboxMin"], rtol=1e-6)
    np.testing.assert_allclose(hi, info["bboxMax"], rtol=1e-6)


def test_ply_round_trip_is_exact_and_writes_the_bytes_of_convert(work, stripes):
    model = splatwarp.read(stripes)
    splatwarp.write(model, work / "round.ply")
    cli("convert", stripes, work / "convert.ply")
    assert (work / "round.ply").read_bytes() == (work / "convert.ply").read_bytes()
    again = splatwarp.read(work / "round.ply")
    for name in ("positions", "scales", "rotations", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(again, name), getattr(model, name))


def test_other_formats_read_back_as_the_cli_converts_them(work, stripes):
    model = splatwarp.read(stripes)
    for ext in (".spz", ".glb", ".vdb", ".splat"):
        splatwarp.write(model, work / ("py" + ext))
        cli("convert", stripes, work / ("cli" + ext), *(["--points"] if ext == ".vdb" else []))
        ours, theirs = splatwarp.read(work / ("py" + ext)), splatwarp.read(work / ("cli" + ext))
        assert len(ours) == len(model)
        for name in ("positions", "scales", "rotations", "opacities", "sh"):
            np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name))


def test_arrays_are_views_onto_the_model(work, stripes):
    model = splatwarp.read(stripes)
    positions = model.positions
    assert np.shares_memory(model.sh_dc, model.sh) and np.shares_memory(model.sh_rest, model.sh)
    positions[7] = (1.5, -2.0, 0.25)
    model.opacities[3] = 2.0
    model.sh_rest[5, 1, 2] = 0.125
    np.testing.assert_array_equal(model.positions[7], [1.5, -2.0, 0.25])
    splatwarp.write(model, work / "mutated.ply")
    back = splatwarp.read(work / "mutated.ply")
    np.testing.assert_array_equal(back.positions[7], [1.5, -2.0, 0.25])
    assert back.opacities[3] == 2.0 and back.sh[5, 2, 2] == 0.125
    scales = splatwarp.read(stripes).scales  # the array keeps its model alive
    gc.collect()
    np.testing.assert_array_equal(scales, splatwarp.read(stripes).scales)


def test_from_arrays_builds_the_same_model(work, stripes):
    model = splatwarp.read(stripes)
    built = splatwarp.Model.from_arrays(model.positions, model.scales, model.rotations, model.opacities,
                                        model.sh_dc, model.sh_rest)
    splatwarp.write(built, work / "built.ply")
    assert (work / "built.ply").read_bytes() == Path(stripes).read_bytes()
    plain = splatwarp.Model.from_arrays(model.positions.astype(np.float64), model.scales, model.rotations,
                                        model.opacities, model.sh_dc)
    assert plain.sh_degree == 0 and len(plain) == len(model)


def test_bad_arrays_are_value_errors_naming_what_is_wrong(stripes):
    m = splatwarp.read(stripes)
    with pytest.raises(ValueError, match="positions must have shape"):
        splatwarp.Model.from_arrays(m.positions[:, :2], m.scales, m.rotations, m.opacities, m.sh_dc)
    with pytest.raises(ValueError, match="opacities must have shape .* N = 2000"):
        splatwarp.Model.from_arrays(m.positions, m.scales, m.rotations, m.opacities[:10], m.sh_dc)
    with pytest.raises(ValueError, match="sh_rest holds 2 coefficients"):
        splatwarp.Model.from_arrays(m.positions, m.scales, m.rotations, m.opacities, m.sh_dc, np.zeros((2000, 2, 3)))
    bad = m.positions.copy()
    bad[3, 1] = np.nan
    with pytest.raises(splatwarp.Error, match="Gaussian 3: property 'y' is nan") as caught:
        splatwarp.Model.from_arrays(bad, m.scales, m.rotations, m.opacities, m.sh_dc, m.sh_rest)
    assert isinstance(caught.value, ValueError)
    kept = splatwarp.Model.from_arrays(bad, m.scales, m.rotations, m.opacities, m.sh_dc, m.sh_rest, drop_invalid=True)
    assert len(kept) == len(m) - 1


def test_bad_files_raise_the_message_the_cli_prints(work):
    truncated = work / "truncated.ply"
    truncated.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nend_header\n\0\0")
    missing = work / "missing.ply"
    for path in (truncated, missing):
        expected = cli_error(cli("convert", path, work / "never.ply", ok=False))
        with pytest.raises(splatwarp.Error) as caught:
            splatwarp.read(path)
        assert str(caught.value) == expected


def test_deform_equals_the_cli_byte_for_byte(work, stripes, cli_deform):
    result = splatwarp.deform(stripes, BEND, output=work / "py-bend", **FAST)
    for name in ("baseline.ply", "deformed.ply"):
        assert (work / "py-bend" / name).read_bytes() == (cli_deform / name).read_bytes(), name
    cli_report = json.loads((cli_deform / "report.json").read_text())
    assert result.report["stage2"]["fieldError"] == cli_report["stage2"]["fieldError"]
    # In memory, the spec as a dict: the same models.
    memory = splatwarp.deform(splatwarp.read(stripes), json.loads(BEND.read_text()), **FAST)
    splatwarp.write(memory.stage1, work / "mem-baseline.ply")
    splatwarp.write(memory.result, work / "mem-deformed.ply")
    assert (work / "mem-baseline.ply").read_bytes() == (cli_deform / "baseline.ply").read_bytes()
    assert (work / "mem-deformed.ply").read_bytes() == (cli_deform / "deformed.ply").read_bytes()
    assert memory.report["stage1"]["fieldError"] == cli_report["stage1"]["fieldError"]


def test_deform_stage1_only_and_the_paper_recipe_equal_the_cli(work, stripes):
    cli("deform", stripes, "--spec", BEND, "-o", work / "cli-paper", "--recipe", "paper", "--stage1-only")
    result = splatwarp.deform(stripes, BEND, recipe="paper", stage1_only=True)
    assert result.result is None
    splatwarp.write(result.stage1, work / "paper-baseline.ply")
    assert (work / "paper-baseline.ply").read_bytes() == (work / "cli-paper" / "baseline.ply").read_bytes()


def test_deform_settings_are_checked_as_flags(stripes):
    with pytest.raises(TypeError, match="unexpected keyword argument 'itterations'"):
        splatwarp.deform(stripes, BEND, itterations=5)
    with pytest.raises(ValueError, match="--iterations"):
        splatwarp.deform(stripes, BEND, iterations="many")
    with pytest.raises(ValueError, match="--cells"):
        splatwarp.deform(stripes, BEND, cells=-3)
    # A usage error after parsing: the CLI's message (exit 2), word for word.
    run = cli("deform", stripes, "--spec", BEND, "-o", "never", "--max-gaussians", "1x", "--curve-split-max", 0.1,
              "--budget-merge", "off", ok=False)
    assert run.returncode == 2
    with pytest.raises(splatwarp.Error) as caught:
        splatwarp.deform(stripes, BEND, max_gaussians="1x", curve_split_max=0.1, budget_merge="off")
    assert "splatwarp: usage error: " + str(caught.value) == run.stderr.strip().splitlines()[-1]


def test_render_equals_the_cli_png(work, stripes):
    cli("render", stripes, "-o", work / "one.png", "--size", "96x64")
    np.testing.assert_array_equal(splatwarp.render(stripes, 96, 64), read_png(work / "one.png"))
    cli("render", stripes, "-o", work / "orbit", "--orbit", 4, "--size", "48x48", "--elevation", 35)
    model = splatwarp.read(stripes)
    image = splatwarp.render(model, 48, 48, orbit=4, view=2, elevation=35)
    np.testing.assert_array_equal(image, read_png(work / "orbit" / "view_002.png"))
    floats = splatwarp.render(model, 48, 48, orbit=4, view=2, elevation=35, dtype="float32")
    assert floats.shape == (48, 48, 4) and floats.dtype == np.float32
    np.testing.assert_array_equal(np.rint(np.clip(floats[..., :3], 0, 1) * 255).astype(np.uint8), image)


def test_eval_equals_the_cli_json(stripes, cli_deform):
    deformed = cli_deform / "deformed.ply"
    expected = json.loads(cli("eval", "--rest", stripes, "--deformed", deformed, "--spec", BEND, "--json",
                              "--points", 5000).stdout)
    assert splatwarp.eval(stripes, splatwarp.read(deformed), BEND, points=5000) == expected


def without_uuid(data):
    return re.sub(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}", b"UUID", data)


def test_to_vdb_and_from_vdb_equal_the_cli(work, stripes):
    cli("to-vdb", stripes, "-o", work / "cli.vdb", "--cells", 12)
    splatwarp.to_vdb(stripes, work / "py.vdb", cells=12)
    assert without_uuid((work / "py.vdb").read_bytes()) == without_uuid((work / "cli.vdb").read_bytes())
    with pytest.raises(TypeError, match="'cels'"):
        splatwarp.to_vdb(stripes, work / "never.vdb", cels=16)
    cli("from-vdb", work / "cli.vdb", "-o", work / "from-cli.ply", "--iterations", 3, "--gaussians", 300)
    model, report = splatwarp.from_vdb(work / "cli.vdb", iterations=3, gaussians=300, report=True)
    splatwarp.write(model, work / "from-py.ply")
    assert (work / "from-py.ply").read_bytes() == (work / "from-cli.ply").read_bytes()
    cli_report = json.loads((work / "from-cli.report.json").read_text())
    assert report["heldOut"] == cli_report["heldOut"]


def test_calls_from_threads_take_turns(work, stripes):
    """Two to_vdb calls at once shared the library's one OutputSet: the first to end left it
    dangling, so every later write raised bad_alloc, and a write in another thread was staged
    into the running job's set (its file appeared only when that job committed)."""
    import threading
    model = splatwarp.read(stripes)
    errors = []

    def job(name, cells):
        try:
            splatwarp.to_vdb(model, work / name, cells=cells, device="cpu")
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=job, args=(f"thread{i}.vdb", 8 + 8 * i)) for i in range(3)]
    for t in threads:
        t.start()
    splatwarp.write(model, work / "beside.ply")
    assert (work / "beside.ply").exists()  # written when write() returned, not at another job's commit
    for t in threads:
        t.join()
    assert not errors
    splatwarp.write(model, work / "after.ply")
    assert splatwarp.read(work / "after.ply").positions.shape == model.positions.shape
    assert not list(work.glob(".sw*.tmp"))


def test_paths_with_nul_are_refused_and_other_names_work(work, stripes):
    model = splatwarp.read(stripes)
    with pytest.raises(ValueError, match="null byte"):
        splatwarp.write(model, str(work / "nul.ply") + "\0.splat")
    with pytest.raises(ValueError, match="null byte"):
        splatwarp.read(str(stripes) + "\0garbage")
    assert not (work / "nul.ply").exists()
    odd = os.fsdecode(bytes(work / "caf") + b"\xe9.ply")  # a valid Linux name that is not UTF-8
    splatwarp.write(model, odd)
    assert len(splatwarp.read(odd)) == len(model)


def test_models_changed_through_their_views_are_checked_as_files_are(work, stripes):
    bad = splatwarp.read(stripes)
    bad.positions[3, 0] = np.nan
    for call in (lambda: splatwarp.render(bad, 16, 16, device="cpu"),
                 lambda: splatwarp.to_vdb(bad, work / "bad.vdb", cells=8),
                 lambda: splatwarp.deform(bad, BEND, stage1_only=True, cells=8),
                 lambda: splatwarp.eval(stripes, bad, BEND, points=100)):
        with pytest.raises(splatwarp.Error, match="Gaussian 3: property 'x'"):
            call()
    with pytest.raises(splatwarp.Error, match=r"\(deformed model\)"):
        splatwarp.eval(stripes, bad, BEND, points=100)
    assert not (work / "bad.vdb").exists()
    empty = splatwarp.Model()
    with pytest.raises(splatwarp.Error, match="without Gaussians"):
        splatwarp.write(empty, work / "empty.ply")
    assert not (work / "empty.ply").exists()
    z = np.zeros((0, 3), np.float32)
    with pytest.raises(splatwarp.Error, match="no Gaussians"):
        splatwarp.Model.from_arrays(z, z, np.zeros((0, 4), np.float32), np.zeros(0, np.float32), z)


def test_settings_out_of_the_clis_ranges_are_refused(work, stripes):
    model = splatwarp.read(stripes)
    with pytest.raises(splatwarp.Error, match="1 to 100000 views"):
        splatwarp.render(model, 16, 16, orbit=3_000_000, device="cpu")
    for elevation in (float("nan"), 1e30, 90):
        with pytest.raises(splatwarp.Error, match="elevation"):
            splatwarp.render(model, 16, 16, elevation=elevation, device="cpu")
    for width in (32.0, "32", True, 2**40, 0):
        with pytest.raises((TypeError, ValueError), match="whole numbers from 1"):
            splatwarp.render(model, width, 32, device="cpu")
    with pytest.raises(TypeError, match="'help'"):
        splatwarp.deform(model, BEND, help=True)
    cli("to-vdb", stripes, "-o", work / "ranges.vdb", "--cells", 8)
    with pytest.raises(ValueError, match="rounds must be 1 to 100"):
        splatwarp.from_vdb(work / "ranges.vdb", rounds=1000)
