/* The CT model and the range-bearing radar of the nonlinear benchmarks (N1, N2) as compiled
 * callables of kfast's signature (kfast.nonlinear.model.C_SIGNATURE):
 *     void f(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out)
 * X holds k points of n = 5 states (px, py, vx, vy, omega), row-major; dt = 0.1. */
#include <math.h>
#include <stdint.h>

void ct(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    const double dt = 0.1;
    (void)t;
    (void)u;
    for (intptr_t i = 0; i < k; i++) {
        const double *x = X + i * n;
        double *o = out + i * n;
        double w = x[4], S = sin(w * dt), C = cos(w * dt);
        double s = fabs(w) < 1e-9 ? dt : S / w, c = fabs(w) < 1e-9 ? 0.0 : (1 - C) / w;
        o[0] = x[0] + s * x[2] - c * x[3];
        o[1] = x[1] + c * x[2] + s * x[3];
        o[2] = C * x[2] - S * x[3];
        o[3] = S * x[2] + C * x[3];
        o[4] = w;
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
