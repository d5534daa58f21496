"""Pass P2 (the GPU tile planner's atlas) against the NumPy planner: every tile, its part of its
window, its place in the atlas and its round, and every round's rows and the atlas width, equal
to what :mod:`pycinder.focused.plan.plan_numpy` makes.

The reference calls the NumPy planner's own functions (``_phases_of``, ``fitted_width``,
``_layout``) as :func:`~pycinder.focused.plan.plan_numpy.plan_tiles` and ``_place`` chain them, and
a few plans go through :func:`~pycinder.focused.plan.plan_numpy.plan_tiles` itself, whose geometry
is replaced by the windows.
"""

import time

import numpy as np
import pytest

from pycinder.focused.plan import plan_numpy, plan_numpy_windows
from pycinder.errors import GpuMemoryError
from pycinder.gpu.layout import FLAG_SKIP_IF_HIT
from pycinder.focused.plan.p2_atlas import AtlasPlan, AtlasPlanner, atlas_windows

BIG_BUDGET = 2**40


@pytest.fixture(scope="module")
def planner() -> AtlasPlanner:
    return AtlasPlanner()


def reference(kept, w, h, dense, budget, probe, faces) -> AtlasPlan:
    """The NumPy planner's tiles of windows (as plan_tiles with lead=None makes them)."""
    idx = np.flatnonzero(kept)
    z = np.zeros(0, np.int64)
    if len(idx) == 0:
        return AtlasPlan(z, z, z, np.zeros(0, bool), z, z, np.zeros((0, 4), np.int64), z, z,
                         [], plan_numpy.ATLAS_WIDTH, len(kept))
    ww = np.asarray(w, np.float64)[idx].astype(np.int64)
    hh = np.asarray(h, np.float64)[idx].astype(np.int64)
    d = np.asarray(dense, bool)[idx] if faces else None
    plan_pixels = float((ww * hh).sum())
    phases = [p for p in plan_numpy._phases_of(ww, hh, d, None, probe, plan_pixels) if len(p.w)]
    if len(phases) == 1:
        width = plan_numpy.fitted_width(phases[0].w, phases[0].h)
    else:
        width = plan_numpy.fitted_width(np.concatenate([p.w for p in phases]),
                                   np.concatenate([p.h for p in phases]))
    parts = {k: [] for k in ("pair", "u0", "v0", "moved", "shift", "flags", "window", "round",
                             "phase")}
    rows: list[int] = []
    for number, p in enumerate(phases):
        lay = plan_numpy._layout(p.w, p.h, budget, width)
        t = lay.tile
        src = t if p.src is None else p.src[t]
        moved = np.full(len(t), p.moved) if isinstance(p.moved, bool) else p.moved[t]
        parts["pair"].append(idx[src])
        parts["u0"].append(p.u0[t])
        parts["v0"].append(p.v0[t])
        parts["moved"].append(moved)
        assert (lay.shift == np.round(lay.shift)).all()
        parts["shift"].append(lay.shift.astype(np.int64))
        parts["flags"].append(np.full(len(t), p.flags, np.int64))
        parts["window"].append(lay.window)
        parts["round"].append(lay.round + len(rows))   # as concat_plans numbers them
        parts["phase"].append(np.full(len(t), number, np.int64))
        rows += lay.round_rows
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    return AtlasPlan(**cat, round_rows=rows, atlas_width=width,
                     separated=len(kept) - len(idx), windows=len(idx),
                     pixels=int((ww * hh).sum()))


def check(planner, kept, w, h, dense=None, *, budget=BIG_BUDGET, probe=True, faces=True):
    """Run the pass and the reference on the same windows; assert every output equal."""
    kept = np.asarray(kept, bool)
    dense = np.zeros(len(kept), bool) if dense is None else np.asarray(dense, bool)
    got = planner.run(atlas_windows(kept, w, h, dense), budget_pixels=budget, probe=probe,
                      faces=faces)
    ref = reference(kept, w, h, dense, budget, probe, faces)
    assert len(got) == len(ref.pair), (len(got), len(ref.pair))
    for name in ("pair", "u0", "v0", "moved", "shift", "flags", "window", "round", "phase"):
        a, b = getattr(got, name), getattr(ref, name)
        if not np.array_equal(a, b):
            bad = np.flatnonzero((a != b).reshape(len(a), -1).any(axis=1))
            raise AssertionError(f"{name} differs at {len(bad)} tiles, first {bad[:5]}: "
                                 f"{a[bad[:3]].tolist()} != {b[bad[:3]].tolist()}")
    assert got.round_rows == ref.round_rows
    assert got.atlas_width == ref.atlas_width
    assert got.separated == ref.separated
    assert got.windows == ref.windows
    assert got.pixels == ref.pixels
    return got, ref


def random_windows(rng, k, *, kept=0.8, small=0.5, large=0.15, huge=0.0):
    """Windows of every kind: small (probe-sized or less), medium, larger than a tile, huge."""
    kind = rng.random(k)
    w = rng.integers(2, 25, k)
    h = rng.integers(2, 25, k)
    medium = kind >= small
    w[medium] = rng.integers(2, 513, medium.sum())
    h[medium] = rng.integers(2, 129, medium.sum())
    big = kind >= 1 - large - huge
    w[big] = rng.integers(2, 1500, big.sum())
    h[big] = rng.integers(2, 600, big.sum())
    very = kind >= 1 - huge
    w[very] = rng.integers(1000, 5000, very.sum())
    h[very] = rng.integers(300, 2000, very.sum())
    return rng.random(k) < kept, w, h, rng.random(k) < 0.5


# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("size", [(2, 2), (24, 24), (25, 3), (512, 128), (513, 129), (700, 300),
                                  (1, 1)])
@pytest.mark.parametrize("probe", [True, False])
def test_one_window(planner, size, probe):
    check(planner, [True], [size[0]], [size[1]], [True], probe=probe)


def test_nothing_to_plan(planner):
    """No pair, and pairs all apart: no tiles, the empty plan's width, every pair separated."""
    for k in (0, 5):
        got, _ = check(planner, np.zeros(k, bool), np.full(k, 30), np.full(k, 30))
        assert len(got) == 0 and got.round_rows == [] and got.separated == k


def test_many_windows_probed_and_not(planner):
    rng = np.random.default_rng(1)
    for probe in (True, False):
        for faces in (True, False):
            check(planner, *random_windows(rng, 700), probe=probe, faces=faces)


def test_pieces_of_windows_larger_than_a_tile(planner):
    rng = np.random.default_rng(2)
    kept, w, h, dense = random_windows(rng, 300, small=0.2, large=0.4, huge=0.1)
    got, _ = check(planner, kept, w, h, dense, probe=False)
    assert (got.u0 > 0).any() and (got.v0 > 0).any() and got.moved.all()
    got, _ = check(planner, kept, w, h, dense, probe=True)
    assert (got.flags == FLAG_SKIP_IF_HIT).any()


@pytest.mark.parametrize("pixels", ["below", "above"])
def test_probes_around_the_plan_size(planner, pixels):
    """Below PROBE_PLAN pixels (faces given) only dense pairs are probed, and a large window of
    a pair that is not dense goes whole, or in pieces when larger than a tile (the oversize
    case); above it every large window is probed."""
    kept = np.ones(5, bool)
    w = np.array([30, 600, 10, 40, 26])
    h = np.array([30, 90, 10, 20, 5])
    dense = np.array([True, False, True, False, False])
    if pixels == "above":
        w[1], h[1] = 1200, 200
    total = int((w * h).sum())
    assert (total < plan_numpy.PROBE_PLAN) == (pixels == "below")
    got, _ = check(planner, kept, w, h, dense)
    assert sorted(set(got.phase.tolist())) == [0, 1]
    oversize = (got.pair == 1) & (got.phase == 0)
    if pixels == "below":
        assert oversize.sum() == 2 and got.moved[oversize].all()   # 600 x 90: two pieces
        assert not got.moved[got.pair == 2].any()                   # small: whole, not moved
        assert not (got.pair[got.phase == 1] == 3).any()            # not dense: not probed
    else:
        assert (got.pair[got.phase == 1] == 3).any()
    # Every pair dense (faces not given), and probes off.
    check(planner, kept, w, h, dense, faces=False)
    check(planner, kept, w, h, dense, probe=False)
    # No large window of a dense pair: one phase.
    got, _ = check(planner, kept, w, h, np.zeros(5, bool))
    assert pixels == "above" or (got.phase == 0).all()


def test_band_cuts(planner):
    """Wide tiles of one class cross many band ends; their second parts follow each band."""
    rng = np.random.default_rng(3)
    k = 400
    w = rng.integers(200, 513, k)
    h = rng.integers(65, 129, k)
    got, _ = check(planner, np.ones(k, bool), w, h, probe=False)
    assert (got.shift > 0).sum() > 20 and got.atlas_width == plan_numpy.ATLAS_WIDTH
    # Cuts in several classes and both phases.
    check(planner, *random_windows(rng, 1500, small=0.3, large=0.3))


@pytest.mark.parametrize("budget", [0, 1, 64 * 8, 2048 * 24, 2048 * 100, 2048 * 129, 2**20,
                                    2**33 + 12_345])
def test_budgets_small_and_large(planner, budget):
    """Tiny budgets split the bands into many rounds (a band alone when it is over the
    budget); a budget past 32 bits is read whole."""
    rng = np.random.default_rng(4 + budget % 97)
    got, _ = check(planner, *random_windows(rng, 600, small=0.3, large=0.3), budget=budget)
    if budget <= 2048 * 129:
        assert len(got.round_rows) > 5


def test_every_height_class(planner):
    rng = np.random.default_rng(5)
    for lo, hi in zip((1,) + tuple(c + 1 for c in plan_numpy.HEIGHT_CLASSES[:-1]),
                      plan_numpy.HEIGHT_CLASSES):
        k = 60
        h = rng.integers(lo, hi + 1, k)
        w = rng.integers(1, 300, k)
        got, _ = check(planner, np.ones(k, bool), w, h, probe=False)
        rows = np.array(plan_numpy.HEIGHT_CLASSES)[np.searchsorted(plan_numpy.HEIGHT_CLASSES, h)]
        assert set(got.window[:, 3].tolist()) <= set(range(lo, hi + 1))
        assert len(set(rows.tolist())) == 1
    check(planner, np.ones(3000, bool), rng.integers(1, 400, 3000), rng.integers(1, 129, 3000),
          budget=2048 * 200)


@pytest.mark.parametrize("target", [64, 128, 256, 512, 1024, 2048])
def test_fitted_widths(planner, target):
    """Plans whose widest class is just over half of each width, and just at it."""
    for widest in (target // 2 + 1, target):
        if widest < 2:
            continue
        w = np.array([widest // 2, widest - widest // 2, 7, 3])
        h = np.array([20, 20, 100, 5])
        got, _ = check(planner, np.ones(4, bool), w, h, probe=False)
        assert got.atlas_width == max(target, plan_numpy.MIN_ATLAS_WIDTH)
    got, _ = check(planner, [True], [1], [1])
    assert got.atlas_width == plan_numpy.MIN_ATLAS_WIDTH


def test_a_large_plan(planner):
    rng = np.random.default_rng(6)
    kept, w, h, dense = random_windows(rng, 20_000, kept=0.7, small=0.6, large=0.1)
    got, _ = check(planner, kept, w, h, dense, budget=2**22)
    assert len(got) > 20_000 and len(got.round_rows) > 2
    check(planner, kept, w, h, dense, budget=2**22, probe=False)


def test_pixels_past_32_bits(planner):
    """Windows of more than 2**32 pixels together: the total is summed in 64 bits, and a plan
    whose total's low word is under PROBE_PLAN is still a large plan (its large windows are
    probed whether their pairs are dense or not)."""
    got, _ = check(planner, [True, True, False], [70_000, 30, 5], [65_537, 40, 5],
                   budget=2**31)
    assert got.pixels > 2**32
    got, _ = check(planner, [True, True], [65_536, 30], [65_536, 40], [False, False],
                   budget=2**31)
    assert got.pixels == 2**32 + 1200 and (got.phase == 1).any()


def test_too_many_tiles_is_refused(planner):
    with pytest.raises(GpuMemoryError, match="more than"):
        planner.run(atlas_windows([True], [2**32 - 1], [2**20]), budget_pixels=BIG_BUDGET)


def run_encoded(p, windows, budget):
    """Encode the pass (its windows in a buffer another pass could have written), submit, and
    read back: None when the plan did not fit."""
    p.windows.ensure(windows.nbytes)
    p.windows.write(windows)
    encoder = p.gpu.device.create_command_encoder()
    p.encode(encoder, p.windows, len(windows), budget_pixels=budget)
    nbytes = p.copy_out(encoder)
    p.gpu.device.queue.submit([encoder.finish()])
    return p.finish(nbytes)


def test_grow_and_retry_through_encode():
    """A planner too small for the plan reads back None and grows; encoded again, it gives the
    plan. Bands that do not fit ask for a bound of the records; bands that fit, for the records
    exactly."""
    rng = np.random.default_rng(7)
    for capacity, k, kind in ((8, 500, {"large": 0.3}), (50, 100, {"small": 1.0})):
        p = AtlasPlanner(capacity=capacity)
        kept, w, h, dense = random_windows(rng, k, kept=1.0, **kind)
        windows = atlas_windows(kept, w, h, dense)
        assert run_encoded(p, windows, 2**20) is None and p.capacity > capacity
        needed = p.capacity
        plan = run_encoded(p, windows, 2**20)
        ref = reference(kept, w, h, dense, 2**20, True, True)
        for name in ("pair", "u0", "v0", "window", "round", "shift"):
            assert np.array_equal(getattr(plan, name), getattr(ref, name))
        assert plan.round_rows == ref.round_rows
        if capacity == 50:
            assert needed == len(plan)      # the bands fit: the records' count is exact
        else:
            assert needed >= len(plan)


@pytest.mark.parametrize("probe,faces,budget", [(True, True, 2**18), (False, False, 2**16),
                                                (True, False, 2**24)])
def test_plan_tiles_itself(planner, monkeypatch, probe, faces, budget):
    """plan_tiles, its windows replaced by synthetic ones (unit pixels, axes of the world, the
    origin at 0): its pairs, windows, flags, rounds, round rows and width, and its origins
    (u0 + shift, v0 where moved), are the pass's."""
    rng = np.random.default_rng(8)
    k = 900
    kept, w, h, dense = random_windows(rng, k, large=0.2)
    pairs = np.stack([2 * np.arange(k), 2 * np.arange(k) + 1], axis=1)
    face_counts = np.where(np.repeat(dense, 2), plan_numpy.PROBE_FACES, 0)

    def fake_chunk(chunk, tol, bounds, first):
        i = first + np.flatnonzero(kept[first:first + len(chunk)])
        if len(i) == 0:
            return None
        m = len(i)
        return {"pair": i, "bodies": pairs[i], "axes": np.tile(np.eye(3), (m, 1, 1)),
                "origin": np.zeros((m, 3)), "pixel": np.ones(m),
                "w": w[i].astype(np.float64), "h": h[i].astype(np.float64),
                "slab": np.zeros((m, 2)), "flags": np.zeros(m, np.int64)}

    monkeypatch.setattr(plan_numpy_windows, "_plan_chunk", fake_chunk)
    n = 2 * k
    box = np.tile([0.0, 0.0, 0.0], (n, 1)), np.tile([1.0, 1.0, 1.0], (n, 1))
    plan = plan_numpy.plan_tiles(pairs, np.ones(k), *box, *box, np.tile(np.eye(4), (n, 1, 1)),
                            budget_pixels=budget, probe=probe,
                            faces=face_counts if faces else None, chunk=256)
    got = planner.run(atlas_windows(kept, w, h, dense), budget_pixels=budget, probe=probe,
                      faces=faces)
    assert np.array_equal(got.pair, plan.pair)
    assert np.array_equal(got.window, plan.window)
    assert np.array_equal(got.flags, plan.flags)
    assert np.array_equal(got.round, plan.round)
    assert got.round_rows == plan.round_rows
    assert got.atlas_width == plan.atlas_width and got.separated == plan.separated
    origin = np.stack([np.where(got.moved, got.u0, 0) + got.shift,
                       np.where(got.moved, got.v0, 0), np.zeros(len(got))], axis=1)
    assert np.array_equal(origin, plan.origin)


def test_time_of_a_plan_of_6000_windows(planner):
    """Not a limit: the time of one run, for the record (-s shows it)."""
    rng = np.random.default_rng(9)
    windows = atlas_windows(*random_windows(rng, 6000))
    planner.run(windows, budget_pixels=2**22)
    start = time.perf_counter()
    plan = planner.run(windows, budget_pixels=2**22)
    print(f"\nP2 atlas: {len(plan)} tiles of 6000 pairs in "
          f"{1e3 * (time.perf_counter() - start):.1f} ms")
