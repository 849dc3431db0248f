"""Issue 21's steady-state targets for force control without a force sensor, measured.

The paper's motor (J = 3.06e-4 kg m^2, b = 5e-5 N m s/rad, Coulomb 0.01 N m), its nominal
model (J_n = 2.8e-4, b_n = 0), a 16384-count encoder with backward-difference velocity, one
sample of delay and the 0.444 N m torque limit; the HPDOb (order 1, 100 rad/s) as the DOb and,
sharing it, the RTOB minus the viscous friction beyond b_n (the friction model known);
ForceControl(kf = 1000, kv = 40). For a stiff (10 N m/rad) and a soft (0.1 N m/rad) wall at
0 rad and a 0.05 N m step of tau_ref at 0.1 s, it prints the steady-state contact torque as a
ratio to tau_ref (the reference of the same run), the worst error over the last second, the
time after which the error stays within 1 %, and the impact peak. Then an impedance run
(M_d = J_n, D_d = 0.02, K_d = 0.1) against the soft wall with r = 0.5 rad: the rest angle as a
ratio to the target static deflection K_d r / (K_d + k_e). The two walls are run three times:
with the viscous friction model only, with the Coulomb term too (``friction=PLANT``: c tanh(w/v)
with w the measured velocity low-passed at 100 rad/s), and with that term's dead band at the
encoder's velocity resolution through the filter (``coulomb_deadband`` = (1 - exp(-0.1)) q / Ts
= 0.0365 rad/s; also in the step-noise and tracking rows). Then a position-to-force switching run
on the stiff wall (PositionForceSwitch): first contact, switching time, impact peak; and the
MuJoCo wall (MujocoServo(..., wall=0.0)): the RTOB against MuJoCo's contact torque.

    PYTHONPATH=src python benchmarks/bench_force_control.py     # a few seconds
"""

from __future__ import annotations

import numpy as np

from hpdob import Environment, ServoLoop, design_observer, paper, simulate
from hpdob.controllers import ForceControl, ImpedanceControl, PositionForceSwitch
from hpdob.observers import coulomb_velocity_resolution, reaction_torque_observer

TAU_REF = 0.05


def loop(k_e, controller, order=1, bandwidth=100.0, coulomb=False):
    model = paper.NOMINAL.discretize(paper.TS)
    dob = design_observer(model, order=order, bandwidth=bandwidth)
    if coulomb:  # the whole friction model known: viscous + c tanh(w/v), w low-passed
        observer = reaction_torque_observer(dob, friction=paper.PLANT, velocity_filter=100.0)
        if coulomb == "deadband":  # c tanh(dz_d(w)/v), d the encoder's resolution through it
            d = coulomb_velocity_resolution(
                observer, counts_per_rev=paper.VIRTUAL_SENSOR.counts_per_rev
            )
            observer = reaction_torque_observer(dob, friction=paper.PLANT, velocity_filter=100.0,
                                                coulomb_deadband=d)  # fmt: skip
    else:
        observer = reaction_torque_observer(dob, viscous=paper.PLANT.b - paper.NOMINAL.b)
    return ServoLoop(plant=paper.PLANT.replace(environment=Environment(k_e)),
                     nominal=paper.NOMINAL, Ts=paper.TS, observer=observer,
                     controller=controller, sensor=paper.VIRTUAL_SENSOR,
                     actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


def main() -> None:
    print(f"{'wall [N m/rad]':>15}{'tau_env/tau_ref':>17}{'worst last 1 s':>16}"
          f"{'within 1 % after [s]':>22}{'peak [N m]':>12}")  # fmt: skip
    for k_e, duration, coulomb in ((10.0, 3.0, False), (0.1, 60.0, False), (10.0, 3.0, True),
                                   (0.1, 60.0, True), (10.0, 3.0, "deadband"),
                                   (0.1, 60.0, "deadband")):  # fmt: skip
        if coulomb is True and k_e == 10.0:
            print("with the Coulomb term (friction=PLANT, velocity_filter=100 rad/s):")
        if coulomb == "deadband" and k_e == 10.0:
            print("with the Coulomb term and its dead band (coulomb_deadband = 0.0365 rad/s):")
        result = simulate(loop(k_e, ForceControl(1000.0, kv=40.0), coulomb=coulomb),
                          duration=duration,
                          reference=lambda t: (np.where(t >= 0.1, TAU_REF, 0.0), 0 * t, 0 * t),
                          x0=(-0.01, 0.0))  # fmt: skip
        error = np.abs(result.tau_contact - TAU_REF) / TAU_REF
        outside = np.nonzero(error > 0.01)[0]
        settled = result.t[outside[-1] + 1] if outside.size else 0.0
        worst = np.max(error[-1000:])
        print(f"{k_e:>15g}{result.tau_contact[-1] / TAU_REF:>17.6f}{worst:>15.3%}"
              f"{settled:>22.3f}{result.tau_contact.max():>12.4f}")  # fmt: skip
    coulomb_price()
    switching()
    mujoco_wall()
    k_e, K_d, r = 0.1, 0.1, 0.5
    controller = ImpedanceControl(M_d=paper.NOMINAL.J, D_d=0.02, K_d=K_d)
    result = simulate(loop(k_e, controller), duration=60.0, x0=(-0.01, 0.0),
                      reference=lambda t: (np.full_like(t, r), 0 * t, 0 * t))  # fmt: skip
    target = K_d * r / (K_d + k_e)
    print(
        f"impedance on the soft wall: theta/target = {result.theta[-1] / target:.6f} "
        f"(target {target:g} rad, reached {result.theta[-1]:.6f} rad after 60 s)"
    )

    print(
        "tracking tau_ref = 0.05 + 0.02 sin(2 pi 2 t) N m on the stiff wall, RMS over 1-3 s "
        "(RTOB = the DOb, equal bandwidth 100 rad/s; one run each: bench_force_tracking.py "
        "has the seeds and the equal-noise comparison):"
    )
    print(
        f"{'observer':>22}{'RMS tau_reac - tau_env [N m]':>30}{'RMS tau_env - tau_ref [N m]':>30}"
    )
    for name, order, coulomb in (("DOb, viscous", 0, False), ("HPDOb, viscous", 1, False),
                                 ("DOb, viscous + Coulomb", 0, True),
                                 ("HPDOb, viscous + Coulomb", 1, True),
                                 ("DOb, Coulomb dead band", 0, "deadband"),
                                 ("HPDOb, Coulomb dead band", 1, "deadband")):  # fmt: skip

        def reference(t):
            on = t >= 0.1
            return np.where(on, TAU_REF + 0.02 * np.sin(2 * np.pi * 2 * t), 0.0), 0 * t, 0 * t

        result = simulate(loop(10.0, ForceControl(1000.0, kv=40.0), order=order,
                               coulomb=coulomb),
                          reference=reference, duration=3.0, x0=(-0.01, 0.0))  # fmt: skip
        window = result.t >= 1.0
        estimate = result.tau_reac[window] - result.tau_contact[window]
        tracking = result.tau_contact[window] - result.r[window]
        print(f"{name:>22}{np.sqrt(np.mean(estimate**2)):>30.3e}"
              f"{np.sqrt(np.mean(tracking**2)):>30.3e}")  # fmt: skip


def coulomb_price() -> None:
    """The Coulomb term's cost on the stiff wall: RMS of tau_reac - tau_env over 0.2-1 s of the
    force step, the viscous model alone against viscous + Coulomb (velocity low-passed)."""
    for coulomb in (False, True, "deadband"):
        result = simulate(
            loop(10.0, ForceControl(1000.0, kv=40.0), coulomb=coulomb),
            duration=1.0,
            x0=(-0.01, 0.0),
            reference=lambda t: (np.where(t >= 0.1, TAU_REF, 0.0), 0 * t, 0 * t),
        )
        window = result.t >= 0.2
        error = result.tau_reac[window] - result.tau_contact[window]
        model = {False: "viscous", True: "viscous + Coulomb",
                 "deadband": "viscous + Coulomb, dead band"}[coulomb]  # fmt: skip
        print(f"stiff wall, RTOB friction model {model}: RMS tau_reac - tau_env over 0.2-1 s "
              f"{np.sqrt(np.mean(error**2)):.2e} N m")  # fmt: skip


def switching() -> None:
    """PositionForceSwitch: a PD(400, 40) ramp at 0.1 rad/s from -0.02 rad toward the stiff
    wall at 0, force control (kf 1000, kv 40, tau_ref 0.05 N m) from tau_reac >= 0.02 N m."""
    spec = PositionForceSwitch(400.0, 40.0, 1000.0, kv=40.0, tau_ref=TAU_REF, threshold=0.02)
    result = simulate(loop(10.0, spec, coulomb=True), duration=1.5, x0=(-0.02, 0.0),
                      reference=lambda t: (-0.02 + 0.1 * t, 0.1 + 0 * t, 0 * t))  # fmt: skip
    m = result.contact_metrics(TAU_REF)
    k = int(np.argmax(result.tau_reac >= 0.02))
    switched = result.t[k]
    jump = result.u[k] - result.u[k - 1]  # not bumpless: the command's step at the switch
    error = np.abs(result.tau_contact - TAU_REF) / TAU_REF
    settled = result.t[np.nonzero(error > 0.01)[0][-1] + 1]
    print(
        f"switching on the stiff wall: first contact {m['first_contact']:.3f} s, switch "
        f"{switched:.3f} s (command jump {jump:+.4f} N m), impact peak "
        f"{m['impact_peak']:.4f} N m (overshoot {m['overshoot_ratio']:.1%} of tau_ref), "
        f"within 1 % from {settled:.3f} s, "
        f"tau_env/tau_ref at 1.5 s {result.tau_contact[-1] / TAU_REF:.6f}"
    )


def mujoco_wall() -> None:
    """The MuJoCo wall: a 0.1 m link on the paper's motor (MuJoCo friction loss 0.005 N m)
    pressing a wall at 0 rad, the same loop (RTOB minus the viscous friction), a 0.05 N m step;
    the RTOB's error against MuJoCo's contact torque (contact forces through the contact
    Jacobian) over the last 0.5 s of 2 s, as a ratio to the contact torque."""
    try:
        from hpdob import MujocoServo

        servo = MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=0.005, link_length=0.1,
                            wall=0.0)  # fmt: skip
    except ImportError:
        print("MuJoCo wall: skipped (pip install 'hpdob[mujoco]')")
        return
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=100.0)
    observer = reaction_torque_observer(dob, viscous=paper.PLANT.b - paper.NOMINAL.b)
    mj_loop = ServoLoop(plant=servo, nominal=paper.NOMINAL, Ts=paper.TS, observer=observer,
                        controller=ForceControl(1000.0, kv=40.0), sensor=paper.VIRTUAL_SENSOR,
                        actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip
    result = simulate(
        mj_loop,
        duration=2.0,
        x0=(-0.01, 0.0),
        reference=lambda t: (np.where(t >= 0.1, TAU_REF, 0.0), 0 * t, 0 * t),
    )
    tail = slice(-500, None)
    error = np.abs(result.tau_reac[tail] - result.tau_contact[tail]) / result.tau_contact[tail]
    print(
        f"MuJoCo wall: |tau_reac - tau_contact| / tau_contact over the last 0.5 s: "
        f"max {np.max(error):.2e} (target 1e-2); tau_contact/tau_ref at 2 s "
        f"{result.tau_contact[-1] / TAU_REF:.6f}"
    )


if __name__ == "__main__":
    main()
