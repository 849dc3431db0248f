/*
 * Sample loop of a position servo with an exported disturbance observer (examples/c).
 *
 * The plant is simulated here (the paper's motor: J = 3.06e-4 kg m^2, b = 5e-5 N m s/rad,
 * 10 Euler sub-steps per sample) and carries a load torque: 0.05 N m from t = 0.5 s plus
 * 0.02 sin(4 pi t) N m from t = 1 s. A PD position loop designed on the nominal inertia
 * holds theta at 1 rad; the observer (dob.h / dob.c, written by `hpdob export-c`)
 * estimates the lumped disturbance and the loop compensates it. The same run without the
 * compensation shows what the observer buys. Exit status 0 when the observer cuts the
 * largest position error after t = 1.5 s at least tenfold.
 */
#include <math.h>
#include <stdio.h>

#include "dob.h"

#define J_PLANT 3.06e-4 /* true inertia [kg m^2] */
#define B_PLANT 5e-5    /* true viscous friction [N m s/rad] */
#define J_NOM 2.8e-4    /* nominal inertia of the controller and the observer [kg m^2] */
#define KP 400.0        /* PD gains [1/s^2, 1/s], scaled by J_NOM */
#define KD 40.0
#define SUBSTEPS 10
#define PI 3.14159265358979323846

static double load_torque(double t)
{
    double tau = t >= 0.5 ? 0.05 : 0.0;
    if (t >= 1.0) {
        tau += 0.02 * sin(4.0 * PI * t);
    }
    return tau;
}

/* Runs 3 s of the loop; returns the largest |theta - 1| [rad] after t = 1.5 s. */
static double run(int compensate, int verbose)
{
    const double ts = (double)DOB_TS;
    const double reference = 1.0; /* rad */
    double theta = 0.0, omega = 0.0, worst = 0.0;
    long k;
    int i;
    dob_state s;

    dob_init(&s, (dob_real)theta, (dob_real)omega, (dob_real)0.0);
    for (k = 0; k < 3000; ++k) {
        const double t = (double)k * ts;
        /* 1. measure, 2. estimate, 3. control, 4. apply, 5. update -- in this order */
        const dob_real th = (dob_real)theta, om = (dob_real)omega;
        const double tau_hat = (double)dob_estimate(&s, th, om);
        const double u_pd = J_NOM * (KP * (reference - theta) - KD * omega);
        const double u = u_pd + (compensate ? tau_hat : 0.0);
        dob_update(&s, th, om, (dob_real)u);

        for (i = 0; i < SUBSTEPS; ++i) { /* the plant over [t, t + Ts) */
            const double h = ts / SUBSTEPS, tl = t + h * i;
            omega += h * (u - B_PLANT * omega - load_torque(tl)) / J_PLANT;
            theta += h * omega;
        }
        if (t >= 1.5 && fabs(theta - reference) > worst) {
            worst = fabs(theta - reference);
        }
        if (verbose && k % 300 == 0) {
            printf("%5.2f s  theta = %8.5f rad  load = %7.4f N m  tau_hat = %8.5f N m\n", t,
                   theta, load_torque(t), tau_hat);
        }
    }
    return worst;
}

int main(void)
{
    double with_dob, without_dob;
    printf("order %d observer in %s, Ts = %g s\n", DOB_ORDER,
           sizeof(dob_real) == sizeof(float) ? "float" : "double", (double)DOB_TS);
    with_dob = run(1, 1);
    without_dob = run(0, 0);
    printf("largest |theta - 1 rad| after 1.5 s: %.2e rad with the observer, "
           "%.2e rad without\n",
           with_dob, without_dob);
    return with_dob < 0.1 * without_dob ? 0 : 1;
}
