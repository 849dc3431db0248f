"""The block-wise filters and the regression built from them (issue 25: memory), bit for bit
against scipy's ``sosfiltfilt``, numpy's ``gradient`` and the straightforward construction
the regression had before (written out below as the reference)."""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
import pytest
from scipy import signal

from hpdob.identification._lean import (
    decimated_at,
    filtfilt,
    gradient_block,
    gradient_inplace,
    welch,
)
from hpdob.identification._regression import (
    REST_LENGTH,
    REST_SPEED_FRACTION,
    build_regression,
    differentiate,
    instrument_rows,
    resolve_settings,
    rows_inside_border,
)

FILTERS = {
    "butter4": signal.butter(4, 0.05, output="sos"),
    "cheby8": signal.cheby1(8, 0.05, 0.8 / 31, output="sos"),
    "butter2-slow": signal.butter(2, 0.002, output="sos"),
}


def same_bits(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype != np.float64:
        return np.array_equal(a, b)
    return np.array_equal(a.view(np.int64), b.view(np.int64))  # signed zeros, NaN payloads


@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("n", [61, 100, 4097, 20000])
@pytest.mark.parametrize("block", [7, 64, 4096])
def test_filtfilt_in_blocks_is_sosfiltfilt_bit_for_bit(name, n, block):
    sos = FILTERS[name]
    x = np.cumsum(np.random.default_rng(n).standard_normal(n))
    if n <= 3 * (2 * sos.shape[0] + 1):
        with pytest.raises(ValueError, match="padlen"):
            filtfilt(sos, x, block)
        return
    reference = signal.sosfiltfilt(sos, x)
    assert same_bits(filtfilt(sos, x, block), reference)
    rng = np.random.default_rng(block)
    for samples in (
        np.arange(n),
        np.array([0, n - 1]),
        np.sort(rng.choice(n, n // 3, replace=False)),
    ):
        assert same_bits(decimated_at(sos, n, lambda lo, hi: x[lo:hi], samples, block),
                         reference[samples])  # fmt: skip


def _slice(x, lo, hi):
    return x[lo:hi]


def _random_filter(rng):
    """A random low-, high- or band-pass of order 1-10 by one of four designs, in sections."""
    order = int(rng.integers(1, 11))
    band = rng.choice(["lowpass", "highpass", "bandpass"])
    wn = np.sort(rng.uniform(0.002, 0.95, 2)) if band == "bandpass" else rng.uniform(0.002, 0.95)
    design = int(rng.integers(4))
    if design == 0:
        return signal.butter(order, wn, band, output="sos")
    if design == 1:
        return signal.cheby1(order, rng.uniform(0.01, 1.0), wn, band, output="sos")
    if design == 2:
        return signal.cheby2(order, rng.uniform(20, 60), wn, band, output="sos")
    return signal.ellip(order, rng.uniform(0.01, 1.0), rng.uniform(20, 60), wn, band, output="sos")


def _random_signal(rng, n):
    kind = int(rng.integers(3))
    x = rng.standard_normal(n)
    if kind == 1:
        x = np.cumsum(x)
    elif kind == 2:  # quantised steps, as an encoder's position
        x = np.round(np.cumsum(x) * 7.0) / 7.0
    return x * 10.0 ** float(rng.integers(-6, 6))


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "scipy"])
def test_in_place_sections_are_sosfilt_bit_for_bit(compiled, monkeypatch):
    """``_sos_kernel.run`` (the compiled recurrence, or without numba scipy written back) is
    ``scipy.signal.sosfilt`` with its state, forward and over the reversed signal, to the last
    bit, over random filters, signals and states."""
    from hpdob.identification import _sos_kernel

    if not compiled:
        monkeypatch.setattr(_sos_kernel, "sos_kernel", lambda: _sos_kernel._scipy_run)
    rng = np.random.default_rng(25)
    for _ in range(150 if compiled else 30):
        sos = _random_filter(rng)
        x = _random_signal(rng, int(rng.integers(1, 3000)))
        zi = rng.standard_normal((sos.shape[0], 2)) * 10.0 ** float(rng.integers(-3, 3))
        for reverse in (False, True):
            y, zf = signal.sosfilt(sos, x[::-1] if reverse else x, zi=zi)
            mine, state = x.copy(), zi.copy()
            _sos_kernel.run(sos, mine, state, reverse=reverse)
            assert same_bits(mine[::-1] if reverse else mine, y)
            assert same_bits(state, zf)


def test_in_place_sections_refuse_what_they_cannot_write():
    from hpdob.identification import _sos_kernel

    sos = FILTERS["butter4"]
    zi = np.zeros((sos.shape[0], 2))
    x = np.arange(10.0)
    with pytest.raises(ValueError, match="x must be a writeable C-contiguous float64 array"):
        _sos_kernel.run(sos, x[::2], zi)
    x.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        _sos_kernel.run(sos, x, zi)
    with pytest.raises(ValueError, match="zi must be"):
        _sos_kernel.run(sos, np.arange(10.0), zi.astype(np.float32))
    # shapes the compiled loop would read or write past (it has no bounds checks)
    y = np.arange(10.0)
    message = r"zi must be an array of shape \(2, 2\) for 2 sections, got shape \(1, 2\)"
    with pytest.raises(ValueError, match=message):
        _sos_kernel.run(sos, y, np.zeros((1, 2)))
    with pytest.raises(ValueError, match=r"sos must be an array of shape \(sections, 6\)"):
        _sos_kernel.run(sos[:, :5], y, zi)
    with pytest.raises(ValueError, match="x must be a 1-D array"):
        _sos_kernel.run(sos, np.zeros((2, 5)), zi)
    np.testing.assert_array_equal(y, np.arange(10.0))  # refused calls wrote nothing
    np.testing.assert_array_equal(zi, 0.0)


def test_the_compiled_sections_are_used_only_where_they_give_scipys_bits(monkeypatch):
    """A kernel that differs from ``sosfilt`` (as a fused multiply-add would) is replaced by
    scipy's own filter; the compiled one, which agrees here, is kept."""
    pytest.importorskip("numba")
    from hpdob.identification import _sos_kernel

    def fused_like(sos, x, zi, reverse):
        _sos_kernel._scipy_run(sos, x, zi, reverse)
        x[0] = np.nextafter(x[0], np.inf)

    assert not _sos_kernel._agrees(fused_like)
    assert _sos_kernel._agrees(_sos_kernel._scipy_run)
    _sos_kernel.sos_kernel.cache_clear()
    try:
        assert _sos_kernel.sos_kernel() is not _sos_kernel._scipy_run
        monkeypatch.setattr(_sos_kernel, "_agrees", lambda kernel: False)
        _sos_kernel.sos_kernel.cache_clear()
        assert _sos_kernel.sos_kernel() is _sos_kernel._scipy_run
    finally:
        _sos_kernel.sos_kernel.cache_clear()


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "scipy"])
def test_filtfilt_in_place_and_by_default_blocks_is_sosfiltfilt_bit_for_bit(compiled,
                                                                          monkeypatch):  # fmt: skip
    """Random filters and signals: ``filtfilt`` into a new array and over ``x`` itself,
    ``filtfilt_blocks`` with its default blocks (a sixteenth of the signal, at least
    ``SHORT_BLOCK``) and odd ones, all ``sosfiltfilt`` to the last bit."""
    from hpdob.identification import _lean, _sos_kernel

    if not compiled:
        monkeypatch.setattr(_sos_kernel, "sos_kernel", lambda: _sos_kernel._scipy_run)
    rng = np.random.default_rng(2025)
    for trial in range(60 if compiled else 15):
        sos = _random_filter(rng)
        longest = 3 * _lean.SHORT_BLOCK if trial % 4 else 300
        n = _lean.pad_length(sos) + int(rng.integers(1, longest))
        x = _random_signal(rng, n)
        reference = signal.sosfiltfilt(sos, x)
        assert same_bits(filtfilt(sos, x), reference)
        mine = x.copy()
        assert filtfilt(sos, mine, out=mine) is mine
        assert same_bits(mine, reference)
        for block in (None, int(rng.integers(1, n + 2))):
            got = np.full(n, np.nan)
            read = functools.partial(_slice, x)
            for lo, hi, y in _lean.filtfilt_blocks(sos, n, read, block):
                got[lo:hi] = y
            assert same_bits(got, reference)
    # a strided out (every other sample of a longer array) and one over a strided x
    x = np.cumsum(rng.standard_normal(3000))
    reference = signal.sosfiltfilt(FILTERS["cheby8"], x)
    wide = np.zeros(2 * x.size)
    assert filtfilt(FILTERS["cheby8"], x, out=wide[::2]) is not None
    assert same_bits(wide[::2], reference) and not wide[1::2].any()
    wide[::2] = x
    filtfilt(FILTERS["cheby8"], wide[::2], out=wide[::2])
    assert same_bits(wide[::2], reference)
    # what the block-wise filter reads is never written over: its views are copied first
    x = np.cumsum(rng.standard_normal(5000))
    x0 = x.copy()
    list(_lean.filtfilt_blocks(FILTERS["cheby8"], x.size, lambda a, b: x[a:b], 512))
    assert same_bits(x, x0)


@pytest.mark.parametrize("n", [24_841, 200_000])
def test_filtfilt_in_place_holds_no_array_of_the_signal(n):
    """``filtfilt(sos, x, out=x)`` holds the padding and the states only (it held a forward
    and a backward block, the whole signal up to BLOCK samples); into a new array, that
    array; ``decimated_at`` a short block of each kind."""
    import tracemalloc

    from hpdob.identification import _lean

    sos = FILTERS["cheby8"]
    x = np.cumsum(np.random.default_rng(n).standard_normal(n))
    reference = signal.sosfiltfilt(sos, x)
    filtfilt(sos, x[:1000].copy())  # compiled before it is traced
    samples = np.arange(0, n, 10)
    tracemalloc.start()
    try:
        mine = filtfilt(sos, x, out=x)
        in_place = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        rows = decimated_at(sos, n, lambda lo, hi: reference[lo:hi], samples)
        at = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert same_bits(mine, reference)
    assert in_place <= 16_384
    block = _lean.block_of(n)
    # the rows, the states of the blocks, a block read and its copy
    assert at <= 8 * samples.size + 80 * (n // block + 3) + 16 * block + 16_384
    assert same_bits(rows, signal.sosfiltfilt(sos, reference)[samples])


def test_default_blocks_are_short_for_short_signals(monkeypatch):
    """A sixteenth of the signal, from SHORT_BLOCK to BLOCK samples (read when called)."""
    from hpdob.identification import _lean

    assert _lean.block_of(24_841) == _lean.SHORT_BLOCK
    assert _lean.block_of(16 * 10_000) == 10_000
    assert _lean.block_of(10**8) == _lean.BLOCK
    monkeypatch.setattr(_lean, "BLOCK", 1000)
    assert _lean.block_of(10**6) == 1000


@pytest.mark.parametrize("n", [2, 3, 5, 100, 4097])
@pytest.mark.parametrize("block", [1, 7, 4096])
def test_gradient_in_place_and_in_blocks_is_numpy_gradient(n, block):
    x = np.random.default_rng(n).standard_normal(n)
    reference = np.gradient(x, 1e-3)
    assert same_bits(gradient_inplace(x.copy(), 1e-3, block), reference)
    for lo, hi in ((0, n), (0, 1), (n - 1, n), (1, n - 1), (min(2, n - 1), n)):
        assert same_bits(gradient_block(x, lo, hi, 1e-3), reference[lo:hi])


@pytest.mark.parametrize("n", [2, 3, 5, 100, 4097])
def test_gradient_of_blocks_from_the_last_is_numpy_gradient(n):
    """Blocks given from the last to the first, of every size from 1 to the whole signal."""
    from hpdob.identification._lean import gradient_blocks

    rng = np.random.default_rng(n)
    x = np.cumsum(rng.standard_normal(n)) * 1e-3
    reference = np.gradient(x, 1e-3)
    for trial in range(20):
        if trial == 0:
            cuts = [0, n]
        elif trial == 1:
            cuts = list(range(n + 1))  # blocks of one sample
        else:
            inner = rng.choice(np.arange(1, n), min(n - 1, int(rng.integers(0, 12))), replace=False)
            cuts = [0, *sorted(int(c) for c in inner), n]
        pieces = [(lo, hi, x[lo:hi].copy()) for lo, hi in itertools.pairwise(cuts)]
        got = np.full(n, np.nan)
        order = []
        for lo, hi, g in gradient_blocks(reversed(pieces), n, 1e-3):
            got[lo:hi] = g
            order.append(lo)
        assert order == sorted(order, reverse=True)
        assert same_bits(got, reference)


@pytest.mark.parametrize("n", [5000, 100_000])
def test_gradient_in_place_holds_one_block_of_its_own(n):
    """Beside ``f``, one block of ``GRADIENT_BLOCK`` samples at most (a short log's gradient
    held three arrays of its length: the block and the difference's and quotient's
    temporaries), and the same bits with it as without."""
    import tracemalloc

    from hpdob.identification import _lean

    x = np.random.default_rng(n).standard_normal(n)
    reference = np.gradient(x, 1e-3)
    tracemalloc.start()
    try:
        out = gradient_inplace(x, 1e-3)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert same_bits(out, reference)
    assert peak <= 8 * min(n, _lean.GRADIENT_BLOCK) + 4096


@pytest.mark.parametrize("n", [64, 3001, 5000, 20001])
def test_welch_by_segment_is_scipy_welch_bit_for_bit(n):
    """Whole, read as views, and read as new arrays (which it detrends in place); odd and
    even segment lengths."""
    x = np.cumsum(np.random.default_rng(n).standard_normal(n))
    x.flags.writeable = False  # a view read is never written
    for window, nperseg in ((None, min(n, 256)), ("blackmanharris", min(n, 4096))):
        want = signal.welch(
            x, fs=1e3, nperseg=nperseg, **({} if window is None else {"window": window})
        )
        got = welch(x, fs=1e3, nperseg=nperseg, window=window)
        views = welch((n, lambda lo, hi: x[lo:hi]), fs=1e3, nperseg=nperseg, window=window)
        new = welch((n, lambda lo, hi: x[lo:hi] - 0.0), fs=1e3, nperseg=nperseg, window=window)
        for f, p in (got, views, new):
            assert same_bits(f, want[0]) and same_bits(p, want[1])


# --- the regression as it was built before (issue 25), whole arrays at a time -------------


def _decimate(x, factor):
    if factor == 1:
        return np.array(x, dtype=float)
    sos = signal.cheby1(8, 0.05, 0.8 / factor, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)[::factor]


def _observation(velocity, acceleration):
    return np.column_stack([acceleration, velocity, np.sign(velocity), np.ones_like(velocity)])


def _rest_rows_mask(velocity, index, length, margin):
    speed = np.abs(velocity)
    rest_speed = REST_SPEED_FRACTION * float(speed[index].max()) if index.size else 0.0
    slow = speed < rest_speed
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
    starts, stops = edges[0::2], edges[1::2]
    long = stops - starts > length
    resting = np.zeros(speed.size + 1, dtype=np.int64)
    np.add.at(resting, np.maximum(starts[long] - margin, 0), 1)
    np.add.at(resting, np.minimum(stops[long] + margin, speed.size), -1)
    return np.cumsum(resting)[:-1][index] > 0, rest_speed


def kinematics(theta, settings):
    """Filtered position, velocity and acceleration (steps 1-2 of IDIM-LS: the position
    filtered forward and backward, central differences), straightforwardly at full rate."""
    sos = signal.butter(settings.order, settings.cutoff, fs=1.0 / settings.Ts, output="sos")
    position = signal.sosfiltfilt(sos, theta)
    velocity = np.gradient(position, settings.Ts)
    return position, velocity, np.gradient(velocity, settings.Ts)


def reference_regression(theta, u, settings):
    """The construction before issue 25's memory work: full-rate arrays throughout."""
    _, velocity, acceleration = kinematics(theta, settings)
    X = _decimate(_observation(velocity, acceleration), settings.decimation)
    if settings.zoh:
        u = np.concatenate([u[:1], 0.5 * (u[1:] + u[:-1])])
    y = _decimate(u, settings.decimation)
    index = rows_inside_border(theta.size, settings)
    inside = index // settings.decimation
    kept = np.ones(index.size, dtype=bool)
    width = 4 * settings.decimation + 1
    if settings.min_speed > 0.0:
        slow = (np.abs(velocity) < settings.min_speed).astype(float)
        kept = ~(np.convolve(slow, np.ones(width), mode="same") > 0.5)[index]
    rest_speed, rest_rows = 0.0, 0
    if settings.rests:
        resting, rest_speed = _rest_rows_mask(
            velocity, index, REST_LENGTH * settings.decimation, width // 2
        )
        rest_rows = int(np.count_nonzero(resting & kept))
        kept &= ~resting
    at_rows = velocity[index[kept]]
    return {
        "X": X[inside][kept], "y": y[inside][kept], "index": index[kept],
        "forward": float(at_rows[at_rows > 0].sum()),
        "backward": float(-at_rows[at_rows < 0].sum()), "kept": kept, "rest_speed": rest_speed,
        "rest_rows": rest_rows, "velocity0": float(velocity[0]),
        "max_speed": float(np.max(np.abs(velocity))),
    }  # fmt: skip


def _log(n=150_000, Ts=1e-3, seed=3):
    """A quantised two-sine motion with rests and a noisy input (synthetic, seeded); longer
    than two blocks of the block-wise filters."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * Ts
    q = 0.4 * np.sin(2 * np.pi * 0.4 * t) + 0.1 * np.sin(2 * np.pi * 2.3 * t)
    q = np.where((t % 20.0) < 3.0, q[0], q)  # rests of 3 s
    q = np.round(q / 1e-3) * 1e-3
    u = np.gradient(np.gradient(q, Ts), Ts) + 0.01 * rng.standard_normal(n)
    return q, u


CASES = {
    "benchmark rules": {},
    "auto (zoh, rests)": {"zoh": True, "rests": True, "bandwidth": 6.5},
    "min_speed": {"min_speed": 0.05},
    "min_speed and rests": {"min_speed": 0.05, "rests": True, "zoh": True},
    "decimation 1": {"decimation": 1, "cutoff": 30.0, "border": 60, "rests": True},
    "decimation 3": {"decimation": 3, "cutoff": 150.0, "zoh": True},
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_regression_is_the_straightforward_construction_bit_for_bit(case):
    theta, u = _log()
    settings = resolve_settings(1e-3, **CASES[case])
    got = build_regression(theta, u, settings)
    want = reference_regression(theta, u, settings)
    for name, value in want.items():
        assert same_bits(getattr(got, name), value), name
    # the instruments of another trace on the same rows
    other = theta + 1e-4 * np.sin(np.arange(theta.size))
    _, velocity, acceleration = kinematics(other, settings)
    full = _decimate(_observation(velocity, acceleration), settings.decimation)
    inside = rows_inside_border(other.size, settings) // settings.decimation
    assert same_bits(instrument_rows(other, got, settings), full[inside][got.kept])


def test_differentiate_is_the_filtered_kinematics_bit_for_bit():
    theta, _ = _log(20000)
    settings = resolve_settings(1e-3, cutoff=25.0, decimation=1, border=0)
    _, velocity, acceleration = kinematics(theta, settings)
    got = differentiate(theta, 1e-3, cutoff=25.0)
    assert same_bits(got[0], velocity) and same_bits(got[1], acceleration)
    assert math.isfinite(float(got[1].sum()))


@pytest.mark.parametrize("n", [500, 24_841])
def test_band_error_with_its_scale_given_is_the_in_band_relative_error(n):
    """The loop's band error with the filtered input taken block by block (its scale given,
    computed before the simulation) is the straightforward one to the last bit."""
    from hpdob.identification._identify import band_error, band_scale, in_band
    from hpdob.identification._solve import relative_error

    rng = np.random.default_rng(n)
    t = np.arange(n) * 1e-3
    u = np.sin(2 * np.pi * 0.7 * t) + 0.05 * rng.standard_normal(n)
    simulated = u + 0.01 * np.cumsum(rng.standard_normal(n)) / np.sqrt(n)
    settings = resolve_settings(1e-3, bandwidth=5.0)
    reference = relative_error(*in_band((u, simulated), settings))
    assert band_error(u, simulated.copy(), settings) == reference
    mine = simulated.copy()
    assert band_error(u, mine, settings, overwrite=True, scale=band_scale(u, settings)) == reference


@pytest.mark.parametrize("n", [300, 1025, 24_841])
def test_velocity_by_blocks_is_the_filtered_velocity(n):
    from hpdob.identification._regression import filtered_velocity, velocity_blocks

    theta = np.cumsum(np.random.default_rng(n).standard_normal(n)) * 1e-3
    settings = resolve_settings(1e-3, bandwidth=5.0)
    reference = filtered_velocity(theta, settings)
    got = np.full(n, np.nan)
    for lo, hi, v in velocity_blocks(theta, settings):
        got[lo:hi] = v
    assert same_bits(got, reference)


@pytest.mark.parametrize("closed", [False, True], ids=["open loop", "through a loop"])
def test_simulation_fit_without_traces_is_the_fit_with_them(closed):
    """keep=False (the log's velocity block by block beside the kept simulated position, the
    difference over the simulated velocity or the spent command) gives the numbers keep=True
    does; its callback's again() writes the same simulation into both arrays anew."""
    from hpdob.identification import FeedbackLoop
    from hpdob.identification._simfit import simulate_fit

    n, Ts = 6000, 1e-3
    t = np.arange(n) * Ts
    u = 0.02 * np.sin(2 * np.pi * 0.5 * t) + 0.01 * np.sin(2 * np.pi * 3.1 * t)
    parameters = (1.2e-3, 2e-3, 0.003, 0.0)
    theta = np.cumsum(np.cumsum(u)) * Ts * Ts / parameters[0]
    settings = resolve_settings(Ts, bandwidth=5.0)
    loop = FeedbackLoop(theta, kp=0.05, kd=0.002) if closed else None
    kept = {}

    def keep(position, command, again):
        kept["q"] = position
        if closed:
            command[:] = np.nan  # spent (the band error overwrites it)
            position_bits = position.copy()
            again()
            kept["u"] = command.copy()
            assert same_bits(position, position_bits)  # rewritten with the same numbers
        else:
            assert command is None
        return True

    both = simulate_fit(parameters, t, theta, u, loop, settings, keep=True)
    lean = simulate_fit(parameters, t, theta, u, loop, settings, keep=False, simulated=keep)
    assert (lean.position_fit, lean.velocity_fit) == (both.position_fit, both.velocity_fit)
    assert same_bits(kept["q"], both.theta_simulated)
    if closed:
        assert same_bits(kept["u"], both.u_simulated)
    # without a callback: the same numbers (through a loop, the difference over the command)
    alone = simulate_fit(parameters, t, theta, u, loop, settings, keep=False)
    assert (alone.position_fit, alone.velocity_fit) == (both.position_fit, both.velocity_fit)
