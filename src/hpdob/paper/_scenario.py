"""The canonical scenario: the paper's section IV set-up, defined once.

True plant J = 3.06e-4 kg m^2 (Maxon EC 90 flat class), b = 5e-5 N m s/rad, Coulomb friction
0.01 N m (tanh scale 0.01 rad/s); nominal model J_n = 2.8e-4 kg m^2, b_n = 0; Ts = 1 ms;
10 s; PD(kp=50, kd=5) with feed-forward; ideal sensor and actuator; zero initial state
(the virtual experiments: a 16384-count encoder, 0.444 N m limit and one sample of delay).
Reference: quintic step 0 -> 1 rad over 0.2-1.2 s, hold, then 1 + 0.5 (1 - cos(pi (t - 4)))
from t = 4 s. External disturbance: 0.05 N m step at t = 1.5005 s plus
0.02 sin(4 pi (t - 2.5005)) N m from t = 2.5005 s.
"""

from __future__ import annotations

import functools

from .._validation import check_choice
from ..controllers import PD
from ..observers import DisturbanceObserver
from ..simulation import canonical, simulate

# The canonical scenario's constants, defined once in hpdob.simulation (below tune and
# compare_observers, which default to them) and public here.
CONTROLLER = canonical.CONTROLLER
DISTURBANCE = canonical.DISTURBANCE
DURATION = canonical.DURATION
NOMINAL = canonical.NOMINAL
PLANT = canonical.PLANT
REFERENCE = canonical.REFERENCE
TS = canonical.TS
VIRTUAL_ACTUATOR = canonical.VIRTUAL_ACTUATOR
VIRTUAL_SENSOR = canonical.VIRTUAL_SENSOR

__all__ = [
    "CONTROLLER",
    "DISTURBANCE",
    "DURATION",
    "NOMINAL",
    "PLANT",
    "REFERENCE",
    "RUNS",
    "TS",
    "VIRTUAL_ACTUATOR",
    "VIRTUAL_POSITION_CONTROLLER",
    "VIRTUAL_RUNS",
    "VIRTUAL_SENSOR",
    "observer",
    "run",
    "scenario",
]

#: The PD of ``virtual-experiment-position``: its D term takes the observer's velocity
#: estimate instead of the encoder's backward difference (docs/simulation.md).
VIRTUAL_POSITION_CONTROLLER = PD(kp=50.0, kd=5.0, feedforward=True, velocity="observer")

#: Observer of each canonical run (None: PD only); the paper's observers with gain direction
#: (1, 1). ``virtual-experiment`` is the paper's HPDOb-100 on the encoder (differenced
#: velocity); ``virtual-experiment-position`` the position-only observer recommended for it
#: (order 2, every pole at 150 rad/s, docs/analysis.md section 8) with the PD on its velocity.
RUNS = {
    "PD": None,
    "DOb-50": {"order": 0, "bandwidth": 50.0},
    "DOb-100": {"order": 0, "bandwidth": 100.0},
    "DOb-200": {"order": 0, "bandwidth": 200.0},
    "HPDOb-100": {"order": 1, "bandwidth": 100.0},
    "virtual-experiment": {"order": 1, "bandwidth": 100.0},
    "virtual-experiment-position": {"order": 2, "bandwidth": 150.0, "measurement": "position"},
}
#: The runs on the virtual experiment's encoder and actuator.
VIRTUAL_RUNS = ("virtual-experiment", "virtual-experiment-position")


def scenario() -> dict:
    """Keyword arguments of :func:`hpdob.simulate` for the canonical scenario, no observer.

    Returns
    -------
    dict
        A new dict with ``plant`` (:data:`PLANT`), ``nominal`` (:data:`NOMINAL`), ``Ts``,
        ``duration``, ``controller``, ``reference`` and ``disturbance``; add ``observer=``
        (and ``sensor=``, ``actuator=``) to run it.

    References
    ----------
    The paper's section IV (simulation set-up); the values are listed in this module's
    docstring and in ``docs/simulation.md``.

    Examples
    --------
    >>> from hpdob import design_observer, paper, simulate
    >>> kwargs = paper.scenario()
    >>> kwargs["Ts"], kwargs["duration"], kwargs["plant"].J
    (0.001, 10.0, 0.000306)
    >>> obs = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=150.0)
    >>> result = simulate(**{**kwargs, "duration": 2.0}, observer=obs)
    >>> result.t.size
    2000
    """
    return {
        "plant": PLANT,
        "nominal": NOMINAL,
        "Ts": TS,
        "duration": DURATION,
        "controller": CONTROLLER,
        "reference": REFERENCE,
        "disturbance": DISTURBANCE,
    }


def observer(name: str) -> DisturbanceObserver | None:
    """The observer of canonical run ``name``, reset at ``x0 = (0, 0)``, ``tau0 = 0``.

    Parameters
    ----------
    name : str
        One of :data:`RUNS`: ``"PD"``, ``"DOb-50"``, ``"DOb-100"``, ``"DOb-200"``,
        ``"HPDOb-100"``, ``"virtual-experiment"``, ``"virtual-experiment-position"``.

    Returns
    -------
    DisturbanceObserver or None
        A new observer on the nominal model with gain direction ``(1, 1)`` (eq. 25), or None
        for ``"PD"`` (no observer).

    Raises
    ------
    ParameterValueError
        If ``name`` is not a canonical run.

    References
    ----------
    The paper's section IV: DObs at 50, 100 and 200 rad/s, the HPDOb at 100 rad/s (eq. 24,
    poles at ``exp(-g Ts)``).

    Examples
    --------
    >>> from hpdob import paper
    >>> paper.observer("HPDOb-100")
    DisturbanceObserver(order=1, poles=[0.904837, 0.904837], Ts=0.001, J_n=0.00028, b_n=0)
    >>> paper.observer("PD") is None
    True
    """
    check_choice(name, "name", RUNS)
    spec = RUNS[name]
    if spec is None:
        return None
    obs = DisturbanceObserver(NOMINAL.discretize(TS), **spec)  # gain direction (1, 1)
    obs.reset(x0=(0.0, 0.0), tau0=0.0)
    return obs


@functools.lru_cache(maxsize=32)
def _design(spec: tuple):
    """The design of a canonical observer spec (``sorted(spec.items())``), that of
    :func:`observer`: immutable, so made once per spec and process (a run of 1 s would
    otherwise spend as long designing its observer as simulating)."""
    return DisturbanceObserver(NOMINAL.discretize(TS), **dict(spec)).design


def run(name: str, **overrides):
    """Simulate canonical run ``name`` (one of :data:`RUNS`).

    The virtual experiments add :data:`VIRTUAL_SENSOR` and :data:`VIRTUAL_ACTUATOR`;
    ``virtual-experiment-position`` runs :data:`VIRTUAL_POSITION_CONTROLLER`.

    Parameters
    ----------
    name : str
        One of :data:`RUNS` (see :func:`observer`); also the result's label.
    **overrides
        Keyword arguments of :func:`hpdob.simulate` that replace the scenario's, e.g.
        ``duration=2.0``, ``substeps=16`` or ``plant=...``.

    Returns
    -------
    SimulationResult

    Raises
    ------
    ParameterValueError
        If ``name`` is not a canonical run, or an override is rejected by
        :func:`hpdob.simulate`.

    References
    ----------
    The paper's section IV and Figs. 2-5 (``hpdob reproduce``).

    Examples
    --------
    >>> from hpdob import paper
    >>> dob = paper.run("DOb-100", duration=3.0).metrics()
    >>> hpdob = paper.run("HPDOb-100", duration=3.0).metrics()
    >>> hpdob["rms_estimation_error"] < dob["rms_estimation_error"]   # the paper's Fig. 4
    True
    """
    check_choice(name, "name", RUNS)
    kwargs = scenario()
    spec = RUNS[name]  # a loop holds the design; the run starts it at x0 = (0, 0), tau0 = 0
    kwargs["observer"] = None if spec is None else _design(tuple(sorted(spec.items())))
    if name in VIRTUAL_RUNS:
        kwargs["sensor"], kwargs["actuator"] = VIRTUAL_SENSOR, VIRTUAL_ACTUATOR
    if name == "virtual-experiment-position":
        kwargs["controller"] = VIRTUAL_POSITION_CONTROLLER
    kwargs["label"] = name
    kwargs.update(overrides)
    return simulate(**kwargs)
