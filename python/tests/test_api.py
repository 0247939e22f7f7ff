"""The Python package against scikit-image's topology oracle on generated shapes and random
volumes, in every sample type and memory order, with its errors, progress and Ctrl-C."""

import json
import math
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import isotopo
from conftest import ROOT, SAMPLE, betti, noise, torus

RNG_SEED = 20261202


def solid(volume, iso, inside="above"):
    v = np.asarray(volume, dtype=np.float64)
    return v > iso if inside == "above" else v < iso


def two_tori():
    a = torus((50, 34, 20), center=[15.5, 16.5, 9.5])
    b = torus((50, 34, 20), center=[33.5, 16.5, 9.5])
    return np.maximum(a, b)


def ball_with_cavity():
    x, y, z = np.meshgrid(*[np.arange(24) - 11.5] * 3, indexing="ij")
    r = np.sqrt(x * x + y * y + z * z)
    return np.minimum(10 - r, r - 4)


SHAPES = {
    "torus": (torus(), 0.0, (1, 1, 0)),
    "two tori": (two_tori(), 0.0, (1, 2, 0)),
    "ball with a cavity": (ball_with_cavity(), 0.0, (1, 0, 1)),
}


# ------------------------------------------------------------------------------------------
# genus


@pytest.mark.parametrize("name", SHAPES)
def test_genus_of_shapes(name):
    volume, iso, want = SHAPES[name]
    assert betti(solid(volume, iso)) == want  # the oracle agrees with the shape's design
    t = isotopo.genus(volume, iso)
    assert (t.b0, t.b1, t.b2) == want
    assert t.chi == t.b0 - t.b1 + t.b2
    assert t.genus == t.b1 == sum(s.genus for s in t.surfaces)
    kinds = [s.encloses for s in t.surfaces]
    assert (kinds.count("material"), kinds.count("cavity")) == (t.b0, t.b2)


def test_genus_on_random_volumes_matches_skimage():
    rng = np.random.default_rng(RNG_SEED)
    checked = 0
    for case in range(40):
        shape = tuple(int(n) for n in rng.integers(6, 22, size=3))
        v = noise(rng, shape, smooth=int(rng.integers(2, 5))).astype(np.float32)
        iso = float(np.quantile(v, rng.uniform(0.3, 0.7)))
        for conn in (6, 26):
            for inside in ("above", "below"):
                want = betti(solid(v, iso, inside), conn)
                t = isotopo.genus(v, iso, inside=inside, connectivity=conn)
                assert (t.b0, t.b1, t.b2) == want, (case, shape, iso, conn, inside)
                checked += 1
    assert checked == 160


def test_genus_surface_areas_follow_spacing():
    a = isotopo.genus(torus(), 0.0).surfaces[0].area
    b = isotopo.genus(torus(), 0.0, spacing=(2, 2, 2)).surfaces[0].area
    assert b == pytest.approx(4 * a, rel=1e-9)
    # The area of the torus 4π²Rr, up to the triangulation of the marching cubes.
    assert a == pytest.approx(4 * math.pi**2 * 12 * 4, rel=0.1)


# ------------------------------------------------------------------------------------------
# analyze


def on_isosurface(points, inside):
    """Whether every point lies on a grid edge between an inside and an outside sample (the
    volume padded with outside, as isotopo reads it)."""
    inside = np.pad(inside, 1)
    for p in np.asarray(points) + 1:
        frac = [abs(c - round(c)) > 1e-9 for c in p]
        if sum(frac) != 1:
            return False
        a = np.floor(p).astype(int)
        b = np.ceil(p).astype(int)
        if inside[tuple(a)] == inside[tuple(b)]:
            return False
    return True


def test_analyze_finds_every_handle_with_loops_on_the_surface():
    rng = np.random.default_rng(RNG_SEED + 1)
    for case in range(25):
        shape = tuple(int(n) for n in rng.integers(8, 20, size=3))
        v = noise(rng, shape, smooth=3)
        iso = float(np.quantile(v, rng.uniform(0.35, 0.65)))
        conn = (6, 26)[case % 2]
        inside = solid(v, iso)
        _, b1, _ = betti(inside, conn)
        handles = isotopo.analyze(v, iso, connectivity=conn, axis="xyz"[case % 3])
        assert len(handles) == b1, (case, shape, iso, conn)
        for h in handles:
            loops = [lp for lp in (h.reeb_loop, h.cross_loop) if lp is not None]
            assert loops and h.size == min(lp.length for lp in loops)
            for lp in loops:
                assert lp.points.ndim == 2 and lp.points.shape[1] == 3
                assert lp.points.dtype == np.float64
                assert len(lp.points) == lp.length
                assert on_isosurface(lp.points, inside), (case, h.id)
                assert lp.encloses in ("material", "void")


def test_analyze_measures_the_torus():
    handles = isotopo.analyze(torus(), 0.0, lengths="mm")
    assert len(handles) == 1
    h = handles[0]
    # The shorter loop goes round the tube (radius 4): 2π·4 = 25.1 mm. The isosurface of the
    # sampled field lies on chords just inside the tube, the loop a polygon on it: within 3%.
    assert h.size_mm == pytest.approx(2 * math.pi * 4, rel=0.03)
    # With voxels twice as large every length in mm doubles; lengths in edges do not change.
    e1 = isotopo.analyze(torus(), 0.0)[0]
    e2 = isotopo.analyze(torus(), 0.0, spacing=(2, 2, 2))[0]
    assert e1.size == e2.size
    assert e2.reeb_loop.length_mm == pytest.approx(2 * e1.reeb_loop.length_mm, abs=2e-3)
    assert e2.to_dict()["size"] == e2.size


def test_analyze_tau_limits_the_search():
    v = torus((60, 60, 20), R=20, r=4)
    full = isotopo.analyze(v, 0.0)[0]
    assert (full.reeb_loop.length, full.cross_loop.length) == (full.size, 128)
    # Loops are measured exactly below tau; beyond it only "at least tau" is known.
    above = isotopo.analyze(v, 0.0, tau=full.size + 1)[0]
    assert above.size == full.size and above.cross_loop is None
    below = isotopo.analyze(v, 0.0, tau=full.size - 4)[0]
    assert below.size >= full.size - 4 and below.cross_loop is None


# ------------------------------------------------------------------------------------------
# simplify


@pytest.mark.parametrize("mode", ["both", "fill", "cut"])
@pytest.mark.parametrize("conn", [6, 26])
def test_simplify_tau_inf_on_random_volumes(mode, conn):
    rng = np.random.default_rng(RNG_SEED + conn + len(mode))
    for case in range(10):
        shape = tuple(int(n) for n in rng.integers(8, 20, size=3))
        v = noise(rng, shape, smooth=3).astype(np.float32)
        iso = float(np.quantile(v, rng.uniform(0.35, 0.65)))
        before = betti(v > iso, conn)
        out, rep = isotopo.simplify(
            v, iso, math.inf, connectivity=conn, fill_only=mode == "fill", cut_only=mode == "cut"
        )
        assert out.dtype == v.dtype and out.shape == v.shape
        after = betti(out > iso, conn)
        assert (rep.genus_before, rep.genus_after) == (before[1], after[1])
        assert (after[0], after[2]) == (before[0], before[2]), (case, mode, conn)
        if mode == "both":
            assert after[1] == 0, (case, conn)
        else:
            # One operation alone may not reach a handle (a fill cannot close a loop round
            # material): what it keeps is reported, and nothing below tau is left otherwise.
            assert after[1] == len(rep.kept)
            assert all(k.get("reason") != "size" for k in rep.kept)
        changed = np.count_nonzero((out > iso) != (v > iso))
        assert changed == rep.samples_changed
        if rep["well_composed"]["well_composed"]:
            other = 26 if conn == 6 else 6
            assert betti(out > iso, other) == after


@pytest.mark.parametrize("conn", [6, 26])
def test_spherical_and_min_component_by_skimage(conn):
    """spherical gives one component, no handle and no cavity; min_component and min_cavity
    leave none smaller, by scikit-image's labels (sizes too)."""
    from skimage.measure import label

    rng = np.random.default_rng(RNG_SEED + 11 + conn)
    fg, bg = (1, 3) if conn == 6 else (3, 1)
    for case in range(6):
        v = noise(rng, (16, 18, 14), smooth=3).astype(np.float32)
        iso = float(np.quantile(v, rng.uniform(0.35, 0.65)))
        b0, _, b2 = betti(v > iso, conn)
        out, rep = isotopo.simplify(v, iso, spherical=True, connectivity=conn)
        assert betti(out > iso, conn) == (min(b0, 1), 0, 0), case
        assert (rep.components_before, rep.cavities_before) == (b0, b2)
        assert (rep.components_after, rep.cavities_after, rep.genus_after) == (min(b0, 1), 0, 0)
        assert rep.parts["components_deleted"] + rep.parts["components_bridged"] == b0 - min(b0, 1)
        assert rep.parts["cavities_filled"] + rep.parts["cavities_opened"] == b2
        out, rep = isotopo.simplify(v, iso, 10, min_component=30, min_cavity=30, connectivity=conn)
        labels = label(np.pad(out > iso, 1), connectivity=fg)
        assert labels.max() == 0 or np.bincount(labels.ravel())[1:].min() >= 30, case
        spaces = label(np.pad(out <= iso, 1, constant_values=True), connectivity=bg)
        sizes = np.bincount(spaces.ravel())
        sizes[spaces[0, 0, 0]] = 0  # the exterior
        assert all(n == 0 or n >= 30 for n in sizes[1:]), case


def test_keep_handles_leaves_that_many_by_skimage():
    rng = np.random.default_rng(RNG_SEED + 13)
    v = noise(rng, (18, 18, 18), smooth=3)
    iso = float(np.quantile(v, 0.5))
    before = betti(v > iso)
    assert before[1] >= 4
    for k in (0, 2, before[1] + 1):
        out, rep = isotopo.simplify(v, iso, keep_handles=k)
        assert betti(out > iso) == (before[0], min(k, before[1]), before[2])
        assert rep.genus_after == min(k, before[1])
    with pytest.raises(ValueError, match="keep_handles"):
        isotopo.simplify(v, iso, 20, keep_handles=2)


def test_spherical_refuses_a_finite_tau():
    with pytest.raises(ValueError, match="spherical"):
        isotopo.simplify(np.zeros((4, 4, 4)), 0.5, 3, spherical=True)
    with pytest.raises(ValueError, match="min_component"):
        isotopo.simplify(np.zeros((4, 4, 4)), 0.5, 3, min_component=0)
    with pytest.raises(ValueError, match="give tau"):
        isotopo.simplify(np.zeros((4, 4, 4)), 0.5)


def test_simplify_inside_below():
    sdf = -two_tori()  # a signed distance field: negative inside
    assert betti(sdf < 0) == (1, 2, 0)
    out, rep = isotopo.simplify(sdf, 0.0, math.inf, inside="below")
    assert (rep.genus_before, rep.genus_after) == (2, 0)
    assert betti(out < 0) == (1, 0, 0)
    assert np.count_nonzero((out < 0) != (sdf < 0)) == rep.samples_changed


def test_simplify_keeps_handles_at_least_tau():
    rng = np.random.default_rng(RNG_SEED + 7)
    for case in range(8):
        v = noise(rng, (18, 18, 18), smooth=3)
        iso = float(np.quantile(v, 0.5))
        sizes = sorted(h.size for h in isotopo.analyze(v, iso))
        tau = sizes[len(sizes) // 2] if sizes else 10
        out, rep = isotopo.simplify(v, iso, tau)
        assert all(r["size"] < tau for r in rep.removed)
        left = isotopo.analyze(out, iso)
        assert all(h.size is None or h.size >= tau for h in left), case
        assert len(left) == rep.genus_after == betti(out > iso)[1]


def test_a_window_of_planes_gives_the_same_result():
    rng = np.random.default_rng(RNG_SEED + 9)
    v = noise(rng, (14, 15, 30))
    iso = float(np.median(v))
    whole, r1 = isotopo.simplify(v, iso, math.inf, max_slices=0)
    window, r2 = isotopo.simplify(v, iso, math.inf, max_slices=4)
    assert np.array_equal(whole, window) and r1.genus_after == r2.genus_after == 0
    a = [h.size for h in isotopo.analyze(v, iso, max_slices=4)]
    assert a == [h.size for h in isotopo.analyze(v, iso)]


def test_simplify_tau_zero_changes_no_topology():
    rng = np.random.default_rng(RNG_SEED + 8)
    v = noise(rng, (16, 16, 16))
    iso = float(np.median(v))
    out, rep = isotopo.simplify(v, iso, 0)
    assert rep.genus_after == rep.genus_before == betti(v > iso)[1]
    assert betti(out > iso) == betti(v > iso)


def test_simplify_equals_the_command_line_on_the_sample(tmp_path):
    exe = Path(os.environ.get("ISOTOPO", ROOT / "target" / "release" / "isotopo"))
    if not exe.exists():
        pytest.skip(f"{exe} not built (cargo build --release)")
    cli_out = tmp_path / "cli.nii.gz"
    report = tmp_path / "cli.json"
    subprocess.run(
        [exe, "simplify", SAMPLE, "--iso", "127.5", "--tau", "20", "-o", cli_out,
         "--report", report, "-q"],
        check=True,
    )
    vol = isotopo.load(SAMPLE)
    out, rep = isotopo.simplify(vol, 127.5, 20, progress=False)  # the file's affine: same mm
    assert np.array_equal(out, isotopo.load(cli_out).array)
    cli = json.loads(report.read_text())
    mine = rep.to_dict()
    # The command line adds what it wrote (output, mesh) and its write time.
    assert set(cli) - set(mine) <= {"output", "mesh", "mesh_euler_characteristic", "seconds",
                                    "seconds_write"}
    assert set(mine) <= set(cli)
    for key in ("genus_before", "genus_after", "samples_changed", "removed", "kept", "mesh_iso"):
        assert mine[key] == cli[key], key


# ------------------------------------------------------------------------------------------
# Sample types and memory orders


def typed(volume, dtype):
    """The torus in `dtype`: inside 1/100/0.5 above an isovalue between, outside below."""
    inside = volume > 0
    dt = np.dtype(dtype)
    if dt.kind == "b":
        return inside, 0.5
    if dt.kind == "f":
        return volume.astype(dt), 0.0
    lo, hi = (-50, 50) if dt.kind == "i" else (0, 100)
    return np.where(inside, hi, lo).astype(dt), (lo + hi) / 2


DTYPES = ["bool", "uint8", "int8", "uint16", "int16", "uint32", "int32", "int64", "uint64",
          "float32", "float64", ">i2", ">f4"]


@pytest.mark.parametrize("dtype", DTYPES)
def test_every_sample_type(dtype):
    v, iso = typed(torus(), dtype)
    assert (isotopo.genus(v, iso).b1, len(isotopo.analyze(v, iso))) == (1, 1)
    out, rep = isotopo.simplify(v, iso, math.inf)
    assert out.dtype == v.dtype and out.shape == v.shape
    assert rep.genus_after == 0 and betti(solid(out, iso)) == (1, 0, 0)


def views():
    """The same torus volume in C order, Fortran order, and as strided and transposed views."""
    base = torus((30, 28, 16), R=9, r=3).astype(np.float32)
    big = np.zeros((60, 29, 18), np.float32)
    big[::2, 1:, 1:-1] = base
    zyx = np.ascontiguousarray(base.transpose(2, 1, 0))
    return {
        "C": np.ascontiguousarray(base),
        "F": np.asfortranarray(base),
        "strided": big[::2, 1:, 1:-1],
        "transposed": zyx.transpose(2, 1, 0),
        "reversed": base[::-1, :, ::-1],
    }


def test_every_memory_order_gives_the_same_result():
    results = {}
    for name, v in views().items():
        t = isotopo.genus(v, 0.0)
        out, rep = isotopo.simplify(v, 0.0, math.inf)
        if name == "reversed":
            out = out[::-1, :, ::-1]
        results[name] = (t.b1, rep.genus_after, out)
    base = results["C"]
    assert base[:2] == (1, 0)
    for name, r in results.items():
        assert r[:2] == base[:2], name
        assert np.array_equal(r[2], base[2]) or name == "reversed", name


def test_the_input_is_left_untouched():
    for v in views().values():
        before = v.copy()
        out, _ = isotopo.simplify(v, 0.0, math.inf)
        assert np.array_equal(v, before)
        assert not np.shares_memory(out, v)
        assert not np.array_equal(out, v)  # the handle was removed in the copy
    m = torus() > 0
    m.setflags(write=False)
    out, _ = isotopo.simplify(m, 0.5, math.inf)  # a read-only input is fine
    assert out.flags.writeable and out.dtype == bool


# ------------------------------------------------------------------------------------------
# Bad input


BAD = [
    (lambda: isotopo.genus(np.zeros((4, 4)), 0.5), ValueError, "3-D"),
    (lambda: isotopo.genus(np.zeros((4, 0, 4)), 0.5), ValueError, "empty"),
    (lambda: isotopo.genus(torus(), float("nan")), ValueError, "finite"),
    (lambda: isotopo.genus(torus(), math.inf), ValueError, "finite"),
    (lambda: isotopo.simplify(torus(), 0.0, -1), ValueError, "tau"),
    (lambda: isotopo.simplify(torus(), 0.0, float("nan")), ValueError, "tau"),
    (lambda: isotopo.analyze(torus(), 0.0, tau=0), ValueError, "tau"),
    (lambda: isotopo.genus(torus().astype(complex), 0.0), TypeError, "complex"),
    (lambda: isotopo.genus(torus().astype(object), 0.0), TypeError, "object"),
    (lambda: isotopo.simplify(torus().astype(np.float16), 0.0, 5), TypeError, "float16"),
    (lambda: isotopo.genus(np.full((3, 3, 3), 2**40), 0.5), TypeError, "32-bit"),
    (lambda: isotopo.genus(torus(), "0"), TypeError, "number"),
    (lambda: isotopo.genus(torus(), 0.0, connectivity=8), ValueError, "connectivity"),
    (lambda: isotopo.genus(torus(), 0.0, inside="in"), ValueError, "inside"),
    (lambda: isotopo.analyze(torus(), 0.0, axis="w"), ValueError, "axis"),
    (lambda: isotopo.simplify(torus(), 0.0, 5, fill_only=True, cut_only=True), ValueError,
     "exclude"),
    (lambda: isotopo.simplify(torus(), 0.0, 5, max_ratio=0.5), ValueError, "ratio"),
    (lambda: isotopo.genus(torus(), 0.0, spacing=(1, 0, 1)), ValueError, "spacing"),
    (lambda: isotopo.genus(torus() > 0, 1.5), ValueError, "bool"),
    (lambda: isotopo.genus(torus(), 0.0, progress=3), TypeError, "progress"),
    (lambda: isotopo.load("/nonexistent/volume.nii.gz"), FileNotFoundError, "volume.nii.gz"),
    (lambda: isotopo.load(Path(__file__)), OSError, "format"),
    (lambda: isotopo.save("/nonexistent/dir/out.nii.gz", torus()), OSError, "does not exist"),
    (lambda: isotopo.save("out.unknown", torus()), ValueError, "extension"),
    (lambda: isotopo.load(12), TypeError, "path"),
    (lambda: isotopo.simplify(torus(), 0.0, 5, max_slices=-1), ValueError, "max_slices"),
]


@pytest.mark.parametrize("call,error,words", BAD, ids=[f"{e.__name__}-{w}" for _, e, w in BAD])
def test_bad_input_raises_a_clear_exception(call, error, words):
    with pytest.raises(error, match=words):
        call()


def test_a_panic_is_an_exception_not_an_abort():
    with pytest.raises(RuntimeError, match="internal error.*a deliberate panic"):
        isotopo._native._panic_for_tests()
    assert isotopo.genus(torus(), 0.0).b1 == 1  # and the module still works


def test_a_memory_limit_too_small_is_a_memoryerror():
    v = torus()
    try:
        isotopo.set_memory_limit("1M")  # below what the interpreter already holds
        assert isotopo.memory_limit() == 1 << 20
        for call in (lambda: isotopo.genus(v, 0.0), lambda: isotopo.simplify(v, 0.0, 5),
                     lambda: isotopo.load(SAMPLE)):
            with pytest.raises(MemoryError, match="not enough memory for .*limit of 1.0 MiB"):
                call()
        isotopo.set_memory_limit(3 << 30)
        assert isotopo.memory_limit() == 3 << 30
        assert isotopo.genus(v, 0.0).b1 == 1
    finally:
        isotopo.set_memory_limit(None)
    assert isotopo.memory_limit() > 1 << 28  # 3/4 of the machine's
    for bad, error in [("lots", ValueError), (0, ValueError), (-5, ValueError),
                       ("0%", ValueError), (True, TypeError), (2.5, TypeError)]:
        with pytest.raises(error):
            isotopo.set_memory_limit(bad)
    assert isotopo.genus(v, 0.0).b1 == 1


def test_a_truncated_file_is_an_oserror(tmp_path):
    good = tmp_path / "v.nii"
    isotopo.save(good, torus().astype(np.float32))
    bad = tmp_path / "cut.nii"
    bad.write_bytes(good.read_bytes()[:1000])
    with pytest.raises(OSError, match="truncated|ends"):
        isotopo.load(bad)


def test_a_scratch_file_that_cannot_be_made_is_an_oserror(tmp_path, monkeypatch):
    # Out of core, the planes beyond the window wait in a scratch file in TMPDIR.
    monkeypatch.setenv("TMPDIR", str(tmp_path / "missing"))
    with pytest.raises(OSError, match="scratch file of the planes.*missing.*TMPDIR"):
        isotopo.analyze(torus(), 0.0, max_slices=2)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    assert len(isotopo.analyze(torus(), 0.0, max_slices=2)) == 1


def test_save_never_overwrites_the_input(tmp_path):
    src = tmp_path / "in.nii.gz"
    isotopo.save(src, torus().astype(np.float32))
    vol = isotopo.load(src)
    with pytest.raises(OSError, match="overwrite"):
        isotopo.save(src, vol.array, like=vol)
    assert np.array_equal(isotopo.load(src).array, vol.array)


# ------------------------------------------------------------------------------------------
# Progress, Ctrl-C and the GIL


def test_progress_callback_sees_each_stage():
    calls = []
    vol = isotopo.load(SAMPLE)
    isotopo.simplify(vol.array, 127.5, 20, progress=lambda s, d, t: calls.append((s, d, t)))
    stages = {s for s, _, _ in calls}
    assert len(stages) >= 3, stages
    assert all(0 <= d <= t or t == 0 for _, d, t in calls)
    assert any(d == t and t > 0 for _, d, t in calls)  # a stage reported complete


def test_an_exception_in_the_callback_stops_the_job():
    def stop(stage, done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        isotopo.simplify(torus(), 0.0, math.inf, progress=stop)


def test_tqdm_bar(capsys):
    pytest.importorskip("tqdm")
    isotopo.genus(torus(), 0.0, progress=True)  # a bar even when not interactive
    err = capsys.readouterr().err
    assert "genus:" in err and "21/21" in err, err  # the genus pass: nz + 1 = 21 planes
    # progress=False draws nothing
    isotopo.genus(torus(), 0.0, progress=False)
    assert capsys.readouterr().err == ""


def test_ctrl_c_raises_keyboard_interrupt_quickly():
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach only the main thread")
    vol = isotopo.load(SAMPLE)
    sent = []

    def interrupt():
        time.sleep(0.5)
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    # Python turns SIGINT into KeyboardInterrupt unless it started with SIGINT ignored (as a
    # background job of a script does): install its handler for the test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=interrupt).start()
        with pytest.raises(KeyboardInterrupt):
            isotopo.simplify(vol.array, 127.5, math.inf, progress=False)
        assert sent and time.perf_counter() - sent[0] < 2.0
    finally:
        signal.signal(signal.SIGINT, previous)


def test_long_calls_release_the_gil():
    vol = isotopo.load(SAMPLE)
    done = threading.Event()
    ticks = 0

    def job():
        isotopo.simplify(vol.array, 127.5, 20, progress=False)
        done.set()

    t = threading.Thread(target=job)
    start = time.perf_counter()
    t.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    elapsed = time.perf_counter() - start
    # Holding the GIL for the whole call would leave this loop one or two ticks.
    assert ticks > 100 * elapsed, (ticks, elapsed)


# ------------------------------------------------------------------------------------------
# Files


@pytest.mark.parametrize("ext", [".nii", ".nii.gz", ".nrrd", ".mgz", ".mha", ".npy", ".tif"])
def test_save_and_load_round_trip(tmp_path, ext):
    v = (torus() * 10).astype(np.int16)
    affine = np.diag([0.5, 0.75, 2.0, 1.0])
    affine[:3, 3] = [10, -20, 30]
    path = tmp_path / f"v{ext}"
    isotopo.save(path, v, affine=affine)
    back = isotopo.load(path)
    assert back.array.shape == v.shape and np.array_equal(back.array, v)
    if ext not in (".npy", ".tif"):
        assert np.allclose(back.affine, affine)
        assert back.spacing == pytest.approx((0.5, 0.75, 2.0))
    # The array saved like the file keeps its header; another type keeps its geometry.
    again = tmp_path / f"again{ext}"
    isotopo.save(again, back.array, like=back)
    assert np.array_equal(isotopo.load(again).array, v)
    as_float = tmp_path / f"float{ext}"
    isotopo.save(as_float, back.array.astype(np.float32), like=back)
    f = isotopo.load(as_float)
    assert f.array.dtype == np.float32 and np.array_equal(f.array, v)
    assert np.allclose(f.affine, back.affine)


def test_load_matches_nibabel_on_the_sample(tmp_path):
    nib = pytest.importorskip("nibabel")
    vol = isotopo.load(SAMPLE)
    img = nib.load(SAMPLE)
    assert np.array_equal(vol.array, np.asanyarray(img.dataobj))
    assert np.allclose(vol.affine, img.affine)
    out = tmp_path / "copy.nii.gz"
    isotopo.save(out, vol.array, like=vol)
    img2 = nib.load(out)
    assert np.array_equal(np.asanyarray(img2.dataobj), vol.array)
    assert np.allclose(img2.affine, img.affine)
    assert img2.header.get_zooms() == img.header.get_zooms()


def test_load_raw_needs_dims_and_type(tmp_path):
    v = np.arange(4 * 5 * 6, dtype=np.uint16).reshape((4, 5, 6), order="F")
    path = tmp_path / "v.raw"
    path.write_bytes(v.tobytes(order="F"))
    back = isotopo.load(path, dims=(4, 5, 6), dtype="uint16", spacing=(1, 2, 3))
    assert np.array_equal(back.array, v) and back.spacing == (1.0, 2.0, 3.0)
    with pytest.raises(ValueError, match=r"dims=\(nx, ny, nz\) and dtype="):
        isotopo.load(path)
    with pytest.raises(OSError, match="truncated|ends"):
        isotopo.load(path, dims=(40, 50, 60), dtype="uint16")
