/*
 * kf_cv.c -- plain fixed-size Kalman filter loop, the "how fast can a
 * straightforward C loop go" baseline for the kfast benchmarks.
 *
 * Sizes are compile-time constants (N states, M observations; default the
 * 2-D constant-velocity model, N = 4, M = 2).  The matrices are still passed
 * in at run time, so nothing about the CV structure (zeros in F or H) is
 * exploited: every product is a full dense N/M-sized loop that the compiler
 * unrolls.  No symmetry tricks, no steady-state shortcut.
 *
 * Per step t (prior x = x(t|t-1), P = P(t|t-1)):
 *   v   = y_t - H x
 *   PHt = P H'                      (N x M)
 *   S   = H PHt + R                 (M x M)
 *   S^-1: M == 2 -> explicit 2x2 inverse (one division);
 *         otherwise (or with -DKF_FORCE_CHOLESKY) Cholesky S = L L'
 *   K   = PHt S^-1
 *   x_f = x + K v
 *   P_f = P - K PHt'                (standard form; K PHt' = K S K')
 *   ll += -0.5 (M log 2pi + log det S + v' S^-1 v)   (one log per step)
 *   x   = F x_f
 *   P   = F P_f F' + Q
 *
 * kf_cv_filter writes x_f (T x N) and P_f (T x N x N) every step and
 * returns the total log-likelihood; kf_cv_loglik only accumulates it.
 *
 * kf_cv_smooth adds the Rauch-Tung-Striebel backward pass (W2).  The forward
 * pass is the loop above; it writes x_f, P_f straight into the smoother's
 * output arrays and stores the priors x(t|t-1), P(t|t-1) in caller-supplied
 * buffers (the forward outputs the backward pass needs).  Then, for
 * t = T-2 .. 0, in place:
 *   A   = P_f(t) F'                               (N x N)
 *   J   = A P_pred(t+1)^-1   via Cholesky P_pred(t+1) = L L' and, for each
 *         row r, the two triangular solves L L' J[r]' = A[r]'
 *   x_s(t) = x_f(t) + J (x_s(t+1) - x_pred(t+1))
 *   P_s(t) = P_f(t) + J (P_s(t+1) - P_pred(t+1)) J'
 * Dense N-sized loops throughout, no symmetry tricks, no lag-one covariances.
 * All arrays are row-major float64.
 *
 * Build: gcc -O3 -march=native -shared -fPIC kf_cv.c -o libkf_cv.so -lm
 */
#include <math.h>
#include <stddef.h>

#ifndef N
#define N 4
#endif
#ifndef M
#define M 2
#endif

static const double LOG_2PI = 1.8378770664093454835606594728112;

typedef struct {
    double F[N][N], H[M][N], Q[N][N], R[M][M];
} model_t;

static void load_model(model_t *md, const double *F, const double *H,
                       const double *Q, const double *R) {
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            md->F[i][j] = F[i * N + j];
            md->Q[i][j] = Q[i * N + j];
        }
    for (int i = 0; i < M; i++) {
        for (int j = 0; j < N; j++) md->H[i][j] = H[i * N + j];
        for (int j = 0; j < M; j++) md->R[i][j] = R[i * M + j];
    }
}

/* One measurement update followed by one time update.  On entry x, P hold
 * the prior; on exit they hold the next prior.  xf, Pf receive the filtered
 * moments.  Returns the log-likelihood term of this step (NaN if S is not
 * positive definite). */
static inline double step(const model_t *md, const double *y, double x[N],
                          double P[N][N], double xf[N], double Pf[N][N]) {
    double v[M], PHt[N][M], S[M][M], K[N][M];

    for (int i = 0; i < M; i++) {
        double s = y[i];
        for (int j = 0; j < N; j++) s -= md->H[i][j] * x[j];
        v[i] = s;
    }
    for (int i = 0; i < N; i++)
        for (int k = 0; k < M; k++) {
            double s = 0.0;
            for (int j = 0; j < N; j++) s += P[i][j] * md->H[k][j];
            PHt[i][k] = s;
        }
    for (int i = 0; i < M; i++)
        for (int k = 0; k < M; k++) {
            double s = md->R[i][k];
            for (int j = 0; j < N; j++) s += md->H[i][j] * PHt[j][k];
            S[i][k] = s;
        }

#if M == 2 && !defined(KF_FORCE_CHOLESKY)
    /* explicit 2x2 inverse: S^-1 = [[s11, -s01], [-s10, s00]] / det */
    double detS = S[0][0] * S[1][1] - S[0][1] * S[1][0];
    if (!(detS > 0.0) || !(S[0][0] > 0.0)) return NAN;
    double idet = 1.0 / detS;
    double Si[2][2] = {{S[1][1] * idet, -S[0][1] * idet}, {-S[1][0] * idet, S[0][0] * idet}};
    for (int r = 0; r < N; r++)
        for (int k = 0; k < M; k++) K[r][k] = PHt[r][0] * Si[0][k] + PHt[r][1] * Si[1][k];
    double Siv0 = Si[0][0] * v[0] + Si[0][1] * v[1];
    double Siv1 = Si[1][0] * v[0] + Si[1][1] * v[1];
    double q = v[0] * Siv0 + v[1] * Siv1;
    double logdet = log(detS);
#else
    /* Cholesky S = L L' (lower triangle only is read); keep 1/L_jj */
    double L[M][M], Linv[M], w[M];
    double detS = 1.0;
    for (int j = 0; j < M; j++) {
        double d = S[j][j];
        for (int k = 0; k < j; k++) d -= L[j][k] * L[j][k];
        if (!(d > 0.0)) return NAN;
        double ljj = sqrt(d);
        L[j][j] = ljj;
        detS *= d;
        double inv = 1.0 / ljj;
        Linv[j] = inv;
        for (int i = j + 1; i < M; i++) {
            double s = S[i][j];
            for (int k = 0; k < j; k++) s -= L[i][k] * L[j][k];
            L[i][j] = s * inv;
        }
    }
    double logdet = log(detS);

    /* K = PHt S^-1 : for each row r of PHt solve L L' k' = r' */
    for (int r = 0; r < N; r++) {
        double z[M];
        for (int i = 0; i < M; i++) {
            double s = PHt[r][i];
            for (int k = 0; k < i; k++) s -= L[i][k] * z[k];
            z[i] = s * Linv[i];
        }
        for (int i = M - 1; i >= 0; i--) {
            double s = z[i];
            for (int k = i + 1; k < M; k++) s -= L[k][i] * K[r][k];
            K[r][i] = s * Linv[i];
        }
    }

    /* Mahalanobis term: w = L^-1 v, q = w'w */
    double q = 0.0;
    for (int i = 0; i < M; i++) {
        double s = v[i];
        for (int k = 0; k < i; k++) s -= L[i][k] * w[k];
        w[i] = s * Linv[i];
        q += w[i] * w[i];
    }

#endif

    for (int i = 0; i < N; i++) {
        double s = x[i];
        for (int k = 0; k < M; k++) s += K[i][k] * v[k];
        xf[i] = s;
    }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double s = P[i][j];
            for (int k = 0; k < M; k++) s -= K[i][k] * PHt[j][k];
            Pf[i][j] = s;
        }

    /* time update */
    double FP[N][N];
    for (int i = 0; i < N; i++) {
        double s = 0.0;
        for (int j = 0; j < N; j++) s += md->F[i][j] * xf[j];
        x[i] = s;
    }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double s = 0.0;
            for (int k = 0; k < N; k++) s += md->F[i][k] * Pf[k][j];
            FP[i][j] = s;
        }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double s = md->Q[i][j];
            for (int k = 0; k < N; k++) s += FP[i][k] * md->F[j][k];
            P[i][j] = s;
        }

    return -0.5 * (M * LOG_2PI + logdet + q);
}

int kf_cv_n(void) { return N; }
int kf_cv_m(void) { return M; }

/* Filter: writes x_filt (T*N) and P_filt (T*N*N); returns total loglik. */
double kf_cv_filter(const double *F, const double *H, const double *Q,
                    const double *R, const double *y, long T,
                    const double *x0, const double *P0, double *x_filt,
                    double *P_filt) {
    model_t md;
    load_model(&md, F, H, Q, R);
    double x[N], P[N][N];
    for (int i = 0; i < N; i++) {
        x[i] = x0[i];
        for (int j = 0; j < N; j++) P[i][j] = P0[i * N + j];
    }
    double ll = 0.0;
    for (long t = 0; t < T; t++) {
        double *xf = x_filt + (size_t)t * N;
        double(*Pf)[N] = (double(*)[N])(P_filt + (size_t)t * N * N);
        ll += step(&md, y + (size_t)t * M, x, P, xf, Pf);
    }
    return ll;
}

/* Log-likelihood only: no per-step output. */
double kf_cv_loglik(const double *F, const double *H, const double *Q,
                    const double *R, const double *y, long T,
                    const double *x0, const double *P0) {
    model_t md;
    load_model(&md, F, H, Q, R);
    double x[N], P[N][N], xf[N], Pf[N][N];
    for (int i = 0; i < N; i++) {
        x[i] = x0[i];
        for (int j = 0; j < N; j++) P[i][j] = P0[i * N + j];
    }
    double ll = 0.0;
    for (long t = 0; t < T; t++) ll += step(&md, y + (size_t)t * M, x, P, xf, Pf);
    return ll;
}


/* RTS smoother (W2).  Outputs x_s (T*N) and P_s (T*N*N); x_pred (T*N) and
 * P_pred (T*N*N) are work buffers that receive the priors x(t|t-1),
 * P(t|t-1).  Returns the total log-likelihood of the forward pass, or NaN if
 * some P(t+1|t) is not positive definite. */
double kf_cv_smooth(const double *F, const double *H, const double *Q,
                    const double *R, const double *y, long T,
                    const double *x0, const double *P0, double *x_s,
                    double *P_s, double *x_pred, double *P_pred) {
    model_t md;
    load_model(&md, F, H, Q, R);
    double x[N], P[N][N];
    for (int i = 0; i < N; i++) {
        x[i] = x0[i];
        for (int j = 0; j < N; j++) P[i][j] = P0[i * N + j];
    }

    /* forward pass: priors into x_pred/P_pred, filtered into x_s/P_s */
    double ll = 0.0;
    for (long t = 0; t < T; t++) {
        double *xp = x_pred + (size_t)t * N;
        double *Pp = P_pred + (size_t)t * N * N;
        for (int i = 0; i < N; i++) {
            xp[i] = x[i];
            for (int j = 0; j < N; j++) Pp[i * N + j] = P[i][j];
        }
        double *xf = x_s + (size_t)t * N;
        double(*Pf)[N] = (double(*)[N])(P_s + (size_t)t * N * N);
        ll += step(&md, y + (size_t)t * M, x, P, xf, Pf);
    }

    /* backward pass, in place over x_s/P_s */
    int bad = 0;
    for (long t = T - 2; t >= 0; t--) {
        double *xs = x_s + (size_t)t * N;
        double(*Ps)[N] = (double(*)[N])(P_s + (size_t)t * N * N);
        const double *xs1 = x_s + (size_t)(t + 1) * N;
        const double(*Ps1)[N] = (const double(*)[N])(P_s + (size_t)(t + 1) * N * N);
        const double *xp1 = x_pred + (size_t)(t + 1) * N;
        const double(*Pp1)[N] = (const double(*)[N])(P_pred + (size_t)(t + 1) * N * N);

        /* A = P_f(t) F' */
        double A[N][N];
        for (int i = 0; i < N; i++)
            for (int j = 0; j < N; j++) {
                double s = 0.0;
                for (int k = 0; k < N; k++) s += Ps[i][k] * md.F[j][k];
                A[i][j] = s;
            }

        /* Cholesky P_pred(t+1) = L L' (lower triangle read) */
        double L[N][N], Linv[N];
        for (int j = 0; j < N; j++) {
            double d = Pp1[j][j];
            for (int k = 0; k < j; k++) d -= L[j][k] * L[j][k];
            if (!(d > 0.0)) { bad = 1; d = NAN; }
            double ljj = sqrt(d);
            L[j][j] = ljj;
            double inv = 1.0 / ljj;
            Linv[j] = inv;
            for (int i = j + 1; i < N; i++) {
                double s = Pp1[i][j];
                for (int k = 0; k < j; k++) s -= L[i][k] * L[j][k];
                L[i][j] = s * inv;
            }
        }

        /* J = A P_pred^-1: row r of J solves P_pred J[r]' = A[r]' */
        double J[N][N];
        for (int r = 0; r < N; r++) {
            double z[N];
            for (int i = 0; i < N; i++) {
                double s = A[r][i];
                for (int k = 0; k < i; k++) s -= L[i][k] * z[k];
                z[i] = s * Linv[i];
            }
            for (int i = N - 1; i >= 0; i--) {
                double s = z[i];
                for (int k = i + 1; k < N; k++) s -= L[k][i] * J[r][k];
                J[r][i] = s * Linv[i];
            }
        }

        /* x_s(t) = x_f(t) + J (x_s(t+1) - x_pred(t+1)) */
        double dx[N];
        for (int i = 0; i < N; i++) dx[i] = xs1[i] - xp1[i];
        for (int i = 0; i < N; i++) {
            double s = xs[i];
            for (int k = 0; k < N; k++) s += J[i][k] * dx[k];
            xs[i] = s;
        }

        /* P_s(t) = P_f(t) + J (P_s(t+1) - P_pred(t+1)) J' */
        double D[N][N], JD[N][N];
        for (int i = 0; i < N; i++)
            for (int j = 0; j < N; j++) D[i][j] = Ps1[i][j] - Pp1[i][j];
        for (int i = 0; i < N; i++)
            for (int j = 0; j < N; j++) {
                double s = 0.0;
                for (int k = 0; k < N; k++) s += J[i][k] * D[k][j];
                JD[i][j] = s;
            }
        for (int i = 0; i < N; i++)
            for (int j = 0; j < N; j++) {
                double s = Ps[i][j];
                for (int k = 0; k < N; k++) s += JD[i][k] * J[j][k];
                Ps[i][j] = s;
            }
    }
    return bad ? NAN : ll;
}
