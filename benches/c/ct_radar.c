/* The CT model and the range-bearing radar of the nonlinear benchmarks (N1, N2) and their
 * Jacobians as compiled callables of kfast's signature (kfast.nonlinear.model.C_SIGNATURE):
 *     void f(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out)
 * X holds k points of n = 5 states (px, py, vx, vy, omega), row-major; dt = 0.1. The formulas
 * are the built-in model's (rust/src/nonlinear/models.rs), operation for operation, so that
 * filters on them match the built-in runs to rounding. */
#include <math.h>
#include <stdint.h>
#include <string.h>

/* s = sin(w dt)/w, c = (1 - cos w dt)/w, C = cos w dt, S = sin w dt (the built-in's turn()) */
static inline void turn(double w, double dt, double *s, double *c, double *C, double *S) {
    if (w == 0.0) {
        *s = dt, *c = 0.0, *C = 1.0, *S = 0.0;
        return;
    }
    double sn = sin(w * dt), cs = cos(w * dt);
    /* 1 - cos as sin^2/(1 + cos) near 0: no cancellation as w -> 0 */
    double one_minus_cos = cs >= 0.0 ? sn * sn / (1.0 + cs) : 1.0 - cs;
    *s = sn / w, *c = one_minus_cos / w, *C = cs, *S = sn;
}

void ct(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    (void)t;
    (void)u;
    for (intptr_t i = 0; i < k; i++) {
        const double *x = X + i * n;
        double *o = out + i * n, s, c, C, S;
        turn(x[4], 0.1, &s, &c, &C, &S);
        o[0] = x[0] + s * x[2] - c * x[3];
        o[1] = x[1] + c * x[2] + s * x[3];
        o[2] = C * x[2] - S * x[3];
        o[3] = S * x[2] + C * x[3];
        o[4] = x[4];
    }
}

/* d ct / d x: k x n x n */
void ct_jac(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    const double dt = 0.1;
    (void)t;
    (void)u;
    for (intptr_t i = 0; i < k; i++) {
        const double *x = X + i * n;
        double vx = x[2], vy = x[3], w = x[4], a = w * dt, s, c, C, S, ds, dc;
        turn(w, dt, &s, &c, &C, &S);
        if (fabs(a) < 0.02) { /* ds/dw, dc/dw by Taylor series: the closed forms are 0/0 at w = 0 */
            double t2 = dt * dt, w2 = w * w;
            ds = -w * dt * t2 / 3.0 + w * w2 * t2 * t2 * dt / 30.0 - w * w2 * w2 * t2 * t2 * t2 * dt / 840.0;
            dc = t2 / 2.0 - w2 * t2 * t2 / 8.0 + w2 * w2 * t2 * t2 * t2 / 144.0;
        } else {
            ds = (a * C - S) / (w * w);
            dc = (a * S - c * w) / (w * w);
        }
        const double J[25] = {
            1.0, 0.0, s, -c, ds * vx - dc * vy,
            0.0, 1.0, c, s, dc * vx + ds * vy,
            0.0, 0.0, C, -S, -dt * (S * vx + C * vy),
            0.0, 0.0, S, C, dt * (C * vx - S * vy),
            0.0, 0.0, 0.0, 0.0, 1.0,
        };
        memcpy(out + i * n * n, J, sizeof J);
    }
}

void radar(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    (void)t;
    (void)u;
    for (intptr_t i = 0; i < k; i++) {
        out[2 * i] = hypot(X[i * n], X[i * n + 1]);
        out[2 * i + 1] = atan2(X[i * n + 1], X[i * n]);
    }
}

/* d radar / d x: k x 2 x n (inf or nan at the sensor, which kfast reports as non-finite) */
void radar_jac(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    (void)t;
    (void)u;
    for (intptr_t i = 0; i < k; i++) {
        const double *x = X + i * n;
        double *J = out + i * 2 * n, r2 = x[0] * x[0] + x[1] * x[1], r = sqrt(r2);
        memset(J, 0, 2 * n * sizeof *J);
        J[0] = x[0] / r, J[1] = x[1] / r;
        J[n] = -x[1] / r2, J[n + 1] = x[0] / r2;
    }
}
