"""Describing functions and the harmonic balance (hpdob.analysis._describing).

Each DF is checked against the first Fourier harmonic of the nonlinearity's output computed
here by brute-force numerical integration (a fine uniform grid over the period), against
its textbook closed form, and against its limits; the harmonic balance against a textbook
relay limit cycle whose frequency and amplitude are known in closed form, and against a
simulation of that sampled relay loop.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import ParameterTypeError, ParameterValueError
from hpdob.analysis import quantiser_df, relay_df, saturation_df, tanh_friction_df
from hpdob.analysis._describing import harmonic_balance

PHI = np.linspace(0.0, 2 * np.pi, 2_000_001)[:-1]  # the period, uniform (spectral accuracy)


def harmonic(f, amplitude: float, centre: float = 0.0) -> tuple[float, float]:
    """(in-phase, quadrature) first-harmonic gain of f(centre + A sin phi), by brute force."""
    y = f(centre + amplitude * np.sin(PHI))
    return (2 * np.mean(y * np.sin(PHI)) / amplitude, 2 * np.mean(y * np.cos(PHI)) / amplitude)


@pytest.mark.parametrize("amplitude", [0.01, 0.3, 2.0])
def test_relay_df_is_the_first_harmonic(amplitude):
    level = 0.01
    inphase, quadrature = harmonic(lambda x: level * np.sign(x), amplitude)
    assert relay_df(amplitude, level=level) == pytest.approx(inphase, rel=1e-5)
    assert abs(quadrature) < 1e-4 * abs(inphase) + 1e-9
    assert relay_df(amplitude, level=level) == 4 * level / (math.pi * amplitude)


@pytest.mark.parametrize("offset", [0.0, 0.13, -0.3, 0.5])
@pytest.mark.parametrize("amplitude", [0.2, 0.45, 0.7, 1.3, 3.7, 12.2])
def test_quantiser_df_is_the_first_harmonic(amplitude, offset):
    q = 0.7  # a step that is not 1: the formula's q and the amplitude's scale both count
    A, x0 = amplitude * q, offset * q
    inphase, quadrature = harmonic(lambda x: q * np.floor(x / q + 0.5), A, x0)  # the encoder
    assert quantiser_df(A, step=q, offset=x0) == pytest.approx(inphase, rel=1e-4, abs=1e-6)
    assert abs(quadrature) < 1e-4 * abs(inphase) + 1e-6


def test_quantiser_df_textbook_form_and_limits():
    q = 2 * np.pi / 16384
    for a in (0.6, 1.5, 2.4, 7.9, 40.0):
        A = a * q
        terms = [math.sqrt(1 - ((2 * i - 1) * q / (2 * A)) ** 2)
                 for i in range(1, 200) if (2 * i - 1) * q < 2 * A]  # fmt: skip
        assert quantiser_df(A, step=q) == pytest.approx(4 * q / (math.pi * A) * sum(terms))
    assert quantiser_df(0.49 * q, step=q) == 0.0  # the dead zone of a centred mid-tread
    assert quantiser_df(1000 * q, step=q) == pytest.approx(1.0, abs=1e-3)
    # on a threshold it is a relay of q/2 around it: 2 q / (pi A) below the next threshold
    assert quantiser_df(0.3 * q, step=q, offset=0.5 * q) == pytest.approx(2 / (math.pi * 0.3))
    grid = quantiser_df(np.array([0.3, 3.0]) * q, step=q)
    assert grid.shape == (2,) and grid[0] == 0.0


@pytest.mark.parametrize("bias", [0.0, 0.05, -0.3])
@pytest.mark.parametrize("amplitude", [0.1, 0.4, 0.5, 0.9, 3.0])
def test_saturation_df_is_the_first_harmonic(amplitude, bias):
    limit = 0.444
    inphase, quadrature = harmonic(lambda x: np.clip(x, -limit, limit), amplitude, bias)
    assert saturation_df(amplitude, limit=limit, bias=bias) == pytest.approx(inphase, rel=1e-5)
    assert abs(quadrature) < 1e-4 * abs(inphase) + 1e-9


def test_saturation_df_textbook_form():
    for r in (1.2, 2.0, 10.0):
        textbook = 2 / math.pi * (math.asin(1 / r) + math.sqrt(1 - 1 / r**2) / r)
        assert saturation_df(r, limit=1.0) == pytest.approx(textbook, rel=1e-14)
    assert saturation_df(0.9, limit=1.0) == 1.0


@pytest.mark.parametrize("amplitude", [1e-4, 0.01, 0.05, 1.0])
def test_tanh_friction_df_is_the_first_harmonic_and_has_its_limits(amplitude):
    c, v = 0.01, 0.01
    inphase, _ = harmonic(lambda x: c * np.tanh(x / v), amplitude)
    assert tanh_friction_df(amplitude, coulomb=c, velocity=v) == pytest.approx(inphase, rel=1e-6)
    small, large = tanh_friction_df([1e-6, 100.0], coulomb=c, velocity=v)
    assert small == pytest.approx(c / v, rel=1e-6)  # the slope
    assert large == pytest.approx(relay_df(100.0, level=c), rel=1e-6)  # the relay


@pytest.mark.parametrize("sigma", [0.004, 0.03])  # below and above v: the two quadratures
def test_tanh_friction_df_with_gaussian_noise_is_the_dual_input_gain(sigma):
    c, v = 0.01, 0.01
    n = np.linspace(-8 * sigma, 8 * sigma, 4001)
    pdf = np.exp(-0.5 * (n / sigma) ** 2)
    pdf /= pdf.sum()
    phi = np.linspace(0, 2 * np.pi, 4001)[:-1]
    for A in (0.003, 0.02, 0.2):
        x = A * np.sin(phi)[:, None] + n[None, :]
        mean = (c * np.tanh(x / v)) @ pdf  # E over the noise, on each phase
        brute = 2 * np.mean(mean * np.sin(phi)) / A
        got = tanh_friction_df(A, coulomb=c, velocity=v, sigma=sigma)
        assert got == pytest.approx(brute, rel=1e-4)
        assert got < tanh_friction_df(A, coulomb=c, velocity=v)  # noise lowers the gain
    # sigma >> v: the mean slope c sqrt(2/pi) / sigma for a small sinusoid
    assert tanh_friction_df(1e-6, coulomb=c, velocity=1e-5, sigma=sigma) == pytest.approx(
        c * math.sqrt(2 / math.pi) / sigma, rel=1e-3
    )


@pytest.mark.parametrize("sigma", [0.0, 0.002, 0.004, 0.03])
def test_tanh_friction_df_with_a_dead_band_is_its_first_harmonic(sigma):
    """The dead-banded term c tanh(dz_d(w)/v) (the RTOB's with coulomb_deadband = d): its DF
    against the first harmonic integrated by brute force (4000 phases, and 4001 noise points
    for the dual-input gain); 0 for a sinusoid inside the band without noise; with d = 0 the
    plain DF itself, to the last bit."""
    c, v, d = 0.01, 0.01, 0.0365
    n = np.linspace(-8 * sigma, 8 * sigma, 4001) if sigma else np.zeros(1)
    pdf = np.exp(-0.5 * (n / sigma) ** 2) if sigma else np.ones(1)
    pdf /= pdf.sum()
    phi = np.linspace(0, 2 * np.pi, 4001)[:-1]
    for A in (0.003, 0.03, 0.05, 0.2, 2.0):
        x = A * np.sin(phi)[:, None] + n[None, :]
        mean = (c * np.tanh(np.sign(x) * np.maximum(np.abs(x) - d, 0.0) / v)) @ pdf
        brute = 2 * np.mean(mean * np.sin(phi)) / A
        got = tanh_friction_df(A, coulomb=c, velocity=v, sigma=sigma, deadband=d)
        assert got == pytest.approx(brute, rel=2e-5, abs=1e-12)
        assert got <= tanh_friction_df(A, coulomb=c, velocity=v, sigma=sigma) * (1 + 1e-12)
        plain = tanh_friction_df(A, coulomb=c, velocity=v, sigma=sigma, deadband=0.0)
        assert plain == tanh_friction_df(A, coulomb=c, velocity=v, sigma=sigma)
    if sigma == 0.0:
        assert tanh_friction_df(0.9 * d, coulomb=c, velocity=v, deadband=d) == 0.0
    with pytest.raises(ParameterValueError, match="deadband must be"):
        tanh_friction_df(1.0, coulomb=c, velocity=v, deadband=-1.0)


def test_bad_inputs_are_refused_naming_the_parameter():
    with pytest.raises(ParameterValueError, match="amplitude must be positive"):
        relay_df(0.0, level=1.0)
    with pytest.raises(ParameterValueError, match="level must be"):
        relay_df(1.0, level=-1.0)
    with pytest.raises(ParameterValueError, match="velocity must be"):
        tanh_friction_df(1.0, coulomb=0.01, velocity=0.0)
    with pytest.raises(ParameterValueError, match="sigma must be"):
        tanh_friction_df(1.0, coulomb=0.01, velocity=0.01, sigma=-1.0)
    with pytest.raises(ParameterValueError, match="offset must be"):
        quantiser_df(1.0, step=1.0, offset=0.7)
    with pytest.raises(ParameterValueError, match="step must be"):
        quantiser_df(1.0, step=0.0)
    with pytest.raises(ParameterValueError, match="bias must be"):
        saturation_df(1.0, limit=0.4, bias=0.5)
    with pytest.raises(ParameterValueError, match="amplitude must be positive"):
        saturation_df([1.0, np.nan], limit=0.4)
    with pytest.raises((ParameterTypeError, ParameterValueError), match="limit must be"):
        saturation_df(1.0, limit="big")


def _relay_loop(Ts: float, level: float):
    """u = -relay(y) around G(s) = 1/(s (s+1) (s+2)), ZOH at Ts: (build, Ad, Bd, C)."""
    from scipy.linalg import expm

    Ac = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -2.0, -3.0]])  # s^3 + 3 s^2 + 2 s
    Bc = np.array([0.0, 0.0, 1.0])
    C = np.array([1.0, 0.0, 0.0])
    M = np.zeros((4, 4))
    M[:3, :3], M[:3, 3] = Ac, Bc
    E = expm(M * Ts)
    Ad, Bd = E[:3, :3], E[:3, 3]

    def build(values):
        return Ad - values["y"] * np.outer(Bd, C), {"y": C}

    return build, Ad, Bd, C


def test_harmonic_balance_finds_the_textbook_relay_limit_cycle():
    """Relay (level h) around 1/(s (s+1) (s+2)): arg G(j w) = -pi at w = sqrt(2), |G| = 1/6,
    so the DF predicts w = sqrt(2) rad/s and A = 4 h |G| / pi = 2 h / (3 pi); sampled at
    1e-4 s the ZOH's half-sample lag moves them by about w Ts / 2."""
    Ts, h = 1e-4, 1.0
    build, *_ = _relay_loop(Ts, h)
    levels = np.geomspace(0.02, 2.0, 41)
    modulus, angle, converged = harmonic_balance(
        build, {"y": lambda a, amp, w: relay_df(a, level=h)}, levels, reference="y", min_angle=1e-6
    )
    assert converged.all()
    crossing = np.flatnonzero(np.diff(np.sign(modulus - 1.0)))
    assert crossing.size == 1
    i = crossing[0]
    assert modulus[i] > 1 > modulus[i + 1]  # grows below, decays above: a stable cycle
    t = (modulus[i] - 1) / (modulus[i] - modulus[i + 1])
    A = math.exp((1 - t) * math.log(levels[i]) + t * math.log(levels[i + 1]))
    w = ((1 - t) * angle[i] + t * angle[i + 1]) / Ts
    assert w == pytest.approx(math.sqrt(2), rel=2e-3)
    assert pytest.approx(2 * h / (3 * math.pi), rel=2e-2) == A  # 2 %: the log grid spacing


def test_relay_limit_cycle_agrees_with_a_simulation_of_the_sampled_relay_loop():
    """The DF's prediction (w = sqrt 2, A = 2h/(3 pi)) against the simulated sampled relay
    loop: its steady oscillation's amplitude and frequency within the DF's known error for
    this plant (the harmonics a third-order plant lets through: a few %)."""
    Ts, h = 1e-3, 1.0
    _, Ad, Bd, C = _relay_loop(Ts, h)
    x = np.array([0.1, 0.0, 0.0])
    n = 60_000
    y = np.empty(n)
    for k in range(n):
        y[k] = C @ x
        x = Ad @ x + Bd * (-h * np.sign(y[k]))
    tail = y[-20_000:]  # 20 s of the settled cycle
    amplitude = 0.5 * (tail.max() - tail.min())
    crossings = np.flatnonzero((tail[:-1] < 0) & (tail[1:] >= 0))
    w = 2 * np.pi / (np.mean(np.diff(crossings)) * Ts)
    assert amplitude == pytest.approx(2 * h / (3 * math.pi), rel=0.06)
    assert w == pytest.approx(math.sqrt(2), rel=0.06)


def test_the_scans_private_dfs_are_the_public_ones_bit_for_bit():
    """contact_limit_cycle calls the DFs' computations without their checks (_one); each
    value is the public function's for the same arguments, to the last bit, across the
    tanh DF's branches (plain, Gauss-Hermite, erf, dead band with and without noise), the
    quantiser's (inside, on and beyond its exact sum) and the saturation's."""
    from hpdob.analysis._describing import _one, _quantiser_df, _saturation_df, _tanh_df

    amplitudes = [1e-300, 1e-7, 3e-3, 0.02, 0.37, 5.0, 1e3, 1e200]
    for a in amplitudes:
        for sigma in (0.0, 0.004, 0.01, 0.03, 0.5):
            for d in (0.0, 0.02, 0.0365):
                public = tanh_friction_df(a, coulomb=0.01, velocity=0.01, sigma=sigma, deadband=d)
                assert _one(_tanh_df, a, 0.01, 0.01, sigma, d) == public
        for offset in (0.0, 0.013, 0.05):
            assert _one(_quantiser_df, a, 0.1, offset) == quantiser_df(a, step=0.1, offset=offset)
        for bias in (0.0, 0.3, -0.9):
            assert _one(_saturation_df, a, 1.0, bias) == saturation_df(a, limit=1.0, bias=bias)
    for bad in (float("nan"), math.inf, 0.0, -1.0, 1e-320):  # refused as the public ones do
        with pytest.raises(ParameterValueError, match=r"^amplitude must be positive finite"):
            _one(_tanh_df, bad, 0.01, 0.01, 0.0, 0.0)


def test_the_viscous_reaction_observer_gives_the_loop_of_the_checked_one():
    """_with_viscous_reaction hands loop_matrices the changed matrices without a new
    LinearObserver; the loop's matrices are those of the LinearObserver of the same
    matrices, bit for bit, for the term on the measured velocity and on omega_hat."""
    from hpdob import Environment, paper
    from hpdob.analysis._describing import _with_viscous_reaction
    from hpdob.analysis._linear_loop import LoopSpec, loop_matrices
    from hpdob.controllers import ForceControl, controller_system
    from hpdob.models import InContact
    from hpdob.observers import LinearObserver, design_observer, reaction_torque_observer

    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=150.0)
    plant = InContact(paper.PLANT.replace(coulomb=0.0, environment=Environment(10.0)))
    controller = controller_system(ForceControl(1000.0, kv=40.0), paper.NOMINAL, paper.TS)

    def matrices(system, signal):
        spec = LoopSpec(plant=plant.discretize(paper.TS), controller=controller, system=system,
                        backward_difference=True, delay=1)  # fmt: skip
        return loop_matrices(spec, measurement_gain=0.8, command_gain=0.9, signals=(signal,))

    for extra in ({}, {"velocity_filter": 100.0}):
        system = reaction_torque_observer(dob, friction=paper.PLANT, **extra).system
        velocity = system.coulomb.velocity
        signal = "omega_m" if velocity == "omega" else "omega_hat"
        for gain in (1e-3, 0.37):
            fast = _with_viscous_reaction(system, velocity, gain)
            assert not (np.array_equal(fast.H, system.H) and np.array_equal(fast.E, system.E))
            checked = LinearObserver(F=system.F, G=system.G, H=fast.H, E=fast.E, N=system.N,
                                     Ts=system.Ts, measures=system.measures,
                                     outputs=system.outputs, model=system.model)  # fmt: skip
            for x, y in zip(matrices(fast, signal)[:4], matrices(checked, signal)[:4],
                            strict=True):  # fmt: skip
                assert np.array_equal(x, y)


def _plain_deadband_mean(x, d, s):
    """The dead-band DF's mean over the noise as plain expressions (the code before its
    buffers and skipped half-lines): the reference the fast one must equal bit for bit."""
    from hpdob.analysis._describing import _BAND_T, _BAND_W, _BAND_X

    upper = np.clip((d - x) / s, -_BAND_T, _BAND_T)
    lower = np.clip((-d - x) / s, -_BAND_T, _BAND_T)
    total = np.zeros_like(x)
    for lo, hi, shift in ((upper, np.full_like(x, _BAND_T), -d),
                          (np.full_like(x, -_BAND_T), lower, d)):  # fmt: skip
        half = 0.5 * (hi - lo)
        t = (lo + half)[..., None] + half[..., None] * _BAND_X
        pdf = np.exp(-0.5 * t**2) / np.sqrt(2.0 * np.pi)
        total += half * ((np.tanh(x[..., None] + s * t + shift) * pdf) @ _BAND_W)
    return total


def test_the_dead_band_mean_is_its_plain_expressions_bit_for_bit():
    """Where a half-line lies beyond the noise's truncation its integrand is skipped, the
    rest computed in buffers: the same value to the last bit as the plain expressions, for
    sinusoids inside (down to amplitudes whose phases all give one integrand), across and far
    beyond the band (every row kept, some, none) and for an array of amplitudes."""
    from hpdob.analysis._describing import _SIN, _deadband_mean

    for s in (0.05, 0.58, 1.5, 3.5):
        for d in (0.3, 2.0, 3.65):
            for ratio in (1e-200, 1e-15, 1e-3, 0.5, 2.0, 4.0, 9.0, 30.0, 200.0, 1e6):
                x = ratio * _SIN
                assert np.array_equal(_deadband_mean(x, d, s), _plain_deadband_mean(x, d, s))
            x = np.multiply.outer(np.geomspace(1e-2, 1e3, 7), _SIN)
            assert np.array_equal(_deadband_mean(x, d, s), _plain_deadband_mean(x, d, s))
            # a phase whose half-line just reaches the truncation (half = 1e-4 there: kept)
            for edge in (d - s * (8.0 - 2e-4), s * (8.0 - 2e-4) - d):
                if edge > 0.0:
                    x = edge / _SIN[200] * _SIN
                    assert np.array_equal(_deadband_mean(x, d, s), _plain_deadband_mean(x, d, s))


def _plain_noisy_tanh_df(a, c, v, sigma):
    """The noisy tanh DF (no dead band) as plain expressions, as the code before its tiny
    amplitudes' shortcuts: the reference the fast one must equal bit for bit."""
    from scipy.special import erf

    from hpdob.analysis._describing import (
        _HERMITE_W,
        _HERMITE_X,
        _PHI,
        _TAIL_U,
        _TAIL_W,
        _W,
    )

    a = np.asarray(a, dtype=float)
    ratio = np.minimum(a / v, 1e150)
    x = np.multiply.outer(ratio, np.sin(_PHI))
    if sigma <= v:
        shift = np.sqrt(2.0) * sigma / v * _HERMITE_X
        f = np.tanh(x[..., None] + shift) @ _HERMITE_W
        small = ratio < 1e-6
        if np.any(small):
            f[small] = x[small] * (np.cosh(shift) ** -2.0 @ _HERMITE_W)
    else:
        s = sigma / v
        xu = x[..., None]
        gap = (1.0 - np.tanh(_TAIL_U)) * _TAIL_W
        pdf = np.exp(-0.5 * ((_TAIL_U - xu) / s) ** 2) - np.exp(-0.5 * ((_TAIL_U + xu) / s) ** 2)
        f = erf(x / (np.sqrt(2.0) * s)) - (pdf @ gap) / (s * np.sqrt(2 * np.pi))
    return 4.0 * c / (np.pi * a) * (f @ (np.sin(_PHI) * _W))


def test_the_noisy_tanh_df_at_tiny_amplitudes_is_its_plain_expressions_bit_for_bit():
    """Below 1e-6 v the Gauss-Hermite branch's tanh sum is replaced by its linear term (so
    it is not computed), and the erf branch's two exps are computed only where u - x and
    u + x differ (elsewhere their difference is 0): the same values to the last bit, for
    single amplitudes and arrays mixing tiny and large ones."""
    c, v = 0.01, 0.01
    amplitudes = [1e-300, 1e-200, 1e-40, 1e-18, 1e-12, 1e-9, 2e-8, 1e-4, 0.05, 3.0]
    for sigma in (0.002, 0.01, 0.0101, 0.035, 0.5):  # Gauss-Hermite up to v, then erf
        for a in amplitudes:
            got = tanh_friction_df(a, coulomb=c, velocity=v, sigma=sigma)
            assert got == float(_plain_noisy_tanh_df(a, c, v, sigma))
        mixed = np.array(amplitudes)
        assert np.array_equal(tanh_friction_df(mixed, coulomb=c, velocity=v, sigma=sigma),
                              _plain_noisy_tanh_df(mixed, c, v, sigma))  # fmt: skip
