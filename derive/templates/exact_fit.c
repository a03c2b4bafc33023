/* The whole exact norm fit of MODEL in one call (simucal.fit.norm_fit.fit_exact, written in C).
 *
 * For each of n_sets data sets of n rows: maximum likelihood on the norm principle,
 *     minimise sum_i |(N_i - h(rho_i u_i, p, aux_i)) / sigma_i|^2,  |u_i| = 1,
 * by Levenberg-Marquardt on p with a 2-D tangent step per direction u_i, the directions
 * eliminated by the Schur complement of their 2x2 blocks, the damping, the convergence
 * test and the covariance at the solution exactly as in fit_exact (so both give the same
 * numbers). h and its Jacobians come from the CasADi function above (dense outputs).
 *
 * Arrays are C-contiguous: N, sig, u (n_sets, n, 3); rho (n_sets, n); aux (n_sets, n, NAUX);
 * p0, p (n_sets, M); cov (n_sets, M, M). status per set: 0 converged, 1 not converged,
 * 2 singular (the plan leaves a combination unobservable), 3 a parameter without any input.
 */
#include <stdlib.h>
#include <string.h>

#define FIT_M MODEL_M
#define FIT_NAUX MODEL_NAUX
/* the parameters each output row depends on (the structural non-zeros of dN/dp, from derive) */
static const int fit_jp_count[3] = MODEL_JP_COUNT;
static const int fit_jp_cols[3][FIT_M] = MODEL_JP_COLS;

static int fit_eval(const double *u, const double *p, const double *aux, double *Nm, double *Ju, double *Jp,
                    casadi_int *iw, double *w) {
  const double *arg[3] = {u, p, aux};
  double *res[3] = {Nm, Ju, Jp};  /* Ju (3x3), Jp (3xM): column-major, dense */
  return MODEL_EVAL(arg, res, iw, w, 0);
}

/* Cholesky of the SPD matrix A (k x k, row-major) in place (lower); 0 if not positive definite. */
static int fit_cholesky(double *A, int k) {
  for (int j = 0; j < k; j++) {
    double s = A[j * k + j];
    for (int l = 0; l < j; l++) s -= A[j * k + l] * A[j * k + l];
    if (!(s > 0)) return 0;
    A[j * k + j] = sqrt(s);
    for (int i = j + 1; i < k; i++) {
      double t = A[i * k + j];
      for (int l = 0; l < j; l++) t -= A[i * k + l] * A[j * k + l];
      A[i * k + j] = t / A[j * k + j];
    }
  }
  return 1;
}

static void fit_chol_solve(const double *L, int k, double *x) {
  for (int i = 0; i < k; i++) {
    double s = x[i];
    for (int l = 0; l < i; l++) s -= L[i * k + l] * x[l];
    x[i] = s / L[i * k + i];
  }
  for (int i = k - 1; i >= 0; i--) {
    double s = x[i];
    for (int l = i + 1; l < k; l++) s -= L[l * k + i] * x[l];
    x[i] = s / L[i * k + i];
  }
}

/* A^-1 = L^-T L^-1 from the Cholesky factor L (row-major, lower) into inv (k x k, row-major, full):
 * the triangular inverse by forward substitution, then the product over its non-zeros. */
static void fit_chol_inverse(const double *L, int k, double *inv) {
  double Li[FIT_M * FIT_M];
  memset(Li, 0, sizeof(double) * k * k);
  for (int j = 0; j < k; j++) {
    Li[j * k + j] = 1.0 / L[j * k + j];
    for (int i = j + 1; i < k; i++) {
      double s = 0;
      for (int l = j; l < i; l++) s -= L[i * k + l] * Li[l * k + j];
      Li[i * k + j] = s / L[i * k + i];
    }
  }
  for (int a = 0; a < k; a++)
    for (int b = a; b < k; b++) {
      double s = 0;
      for (int l = b; l < k; l++) s += Li[l * k + a] * Li[l * k + b];
      inv[a * k + b] = inv[b * k + a] = s;
    }
}

static void fit_tangent(const double *u, double *E) {  /* E (3x2, row-major): e1 = u x a / |.|, e2 = u x e1 */
  double a[3] = {1, 0, 0};
  if (!(fabs(u[0]) < 0.9)) { a[0] = 0; a[1] = 1; }
  double e1[3] = {u[1] * a[2] - u[2] * a[1], u[2] * a[0] - u[0] * a[2], u[0] * a[1] - u[1] * a[0]};
  double s = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
  for (int c = 0; c < 3; c++) e1[c] /= s;
  double e2[3] = {u[1] * e1[2] - u[2] * e1[1], u[2] * e1[0] - u[0] * e1[2], u[0] * e1[1] - u[1] * e1[0]};
  for (int c = 0; c < 3; c++) { E[c * 2] = e1[c]; E[c * 2 + 1] = e2[c]; }
}

static double fit_cost(int n, const double *N, const double *rho, const double *sig, const double *aux,
                       const double *p, const double *u, double *Nm, double *Ju, double *Jp, casadi_int *iw, double *w) {
  double c = 0;
  for (int i = 0; i < n; i++) {
    double x[3] = {rho[i] * u[3 * i], rho[i] * u[3 * i + 1], rho[i] * u[3 * i + 2]};
    fit_eval(x, p, aux + i * FIT_NAUX, Nm, Ju, Jp, iw, w);
    for (int c3 = 0; c3 < 3; c3++) {
      double r = (N[3 * i + c3] - Nm[c3]) / sig[3 * i + c3];
      c += r * r;
    }
  }
  return c;
}

static int fit_one(int n, const double *N, const double *rho, const double *sig, const double *aux, const double *p0,
                   int max_iter, double tol, double *p, double *cov, double *u, double *cost_out, int *iters,
                   double *buf, casadi_int *iw, double *w) {
  const int m = FIT_M;
  double *Jd = buf, *Jq = Jd + 6 * n, *Ainv = Jq + 3 * m * n, *B = Ainv + 4 * n, *gd = B + 2 * m * n;
  double *E = gd + 2 * n, *r = E + 6 * n, *u_new = r + 3 * n;
  double H[FIT_M * FIT_M], Hs[FIT_M * FIT_M], g[FIT_M], dH[FIT_M], dp[FIT_M], p_new[FIT_M];
  double Nm[3], Ju[9], Jp[3 * FIT_M];
  memcpy(p, p0, sizeof(double) * m);
  for (int i = 0; i < n; i++) {  /* initial directions: M u = N - b at u = 0 */
    double z[3] = {0, 0, 0}, M3[9];
    fit_eval(z, p, aux + i * FIT_NAUX, Nm, Ju, Jp, iw, w);
    for (int a = 0; a < 3; a++) for (int b = 0; b < 3; b++) M3[a * 3 + b] = Ju[b * 3 + a];
    double y[3] = {N[3 * i] - Nm[0], N[3 * i + 1] - Nm[1], N[3 * i + 2] - Nm[2]};
    double det = M3[0] * (M3[4] * M3[8] - M3[5] * M3[7]) - M3[1] * (M3[3] * M3[8] - M3[5] * M3[6])
               + M3[2] * (M3[3] * M3[7] - M3[4] * M3[6]);
    double inv[9] = {(M3[4] * M3[8] - M3[5] * M3[7]) / det, (M3[2] * M3[7] - M3[1] * M3[8]) / det,
                     (M3[1] * M3[5] - M3[2] * M3[4]) / det, (M3[5] * M3[6] - M3[3] * M3[8]) / det,
                     (M3[0] * M3[8] - M3[2] * M3[6]) / det, (M3[2] * M3[3] - M3[0] * M3[5]) / det,
                     (M3[3] * M3[7] - M3[4] * M3[6]) / det, (M3[1] * M3[6] - M3[0] * M3[7]) / det,
                     (M3[0] * M3[4] - M3[1] * M3[3]) / det};
    double s = 0;
    for (int a = 0; a < 3; a++) {
      u[3 * i + a] = inv[a * 3] * y[0] + inv[a * 3 + 1] * y[1] + inv[a * 3 + 2] * y[2];
      s += u[3 * i + a] * u[3 * i + a];
    }
    s = sqrt(s);
    for (int a = 0; a < 3; a++) u[3 * i + a] /= s;
  }
  double cost = fit_cost(n, N, rho, sig, aux, p, u, Nm, Ju, Jp, iw, w), lam = 0;
  int it, done = 0;
  for (it = 1; it <= max_iter && !done; it++) {
    memset(H, 0, sizeof H);
    memset(g, 0, sizeof g);
    for (int i = 0; i < n; i++) {  /* residual, Jacobian blocks, Schur complement */
      double x[3] = {rho[i] * u[3 * i], rho[i] * u[3 * i + 1], rho[i] * u[3 * i + 2]};
      fit_eval(x, p, aux + i * FIT_NAUX, Nm, Ju, Jp, iw, w);
      double *Ei = E + 6 * i, *Jdi = Jd + 6 * i, *Jqi = Jq + 3 * m * i, *ri = r + 3 * i;
      fit_tangent(u + 3 * i, Ei);
      for (int a = 0; a < 3; a++) {
        double ws = 1.0 / sig[3 * i + a];  /* one division per component, products after */
        ri[a] = (N[3 * i + a] - Nm[a]) * ws;
        for (int k = 0; k < 2; k++) {
          double v = 0;
          for (int b = 0; b < 3; b++) v += Ju[b * 3 + a] * Ei[b * 2 + k];
          Jdi[a * 2 + k] = -v * rho[i] * ws;
        }
        for (int k = 0; k < m; k++) Jqi[a * m + k] = -Jp[k * 3 + a] * ws;
      }
      double A[4] = {0, 0, 0, 0}, *Bi = B + 2 * m * i, *gdi = gd + 2 * i;
      for (int k = 0; k < 2; k++) {
        gdi[k] = 0;
        for (int a = 0; a < 3; a++) gdi[k] += Jdi[a * 2 + k] * ri[a];
        for (int l = 0; l < 2; l++) for (int a = 0; a < 3; a++) A[k * 2 + l] += Jdi[a * 2 + k] * Jdi[a * 2 + l];
        for (int l = 0; l < m; l++) {
          double v = 0;
          for (int a = 0; a < 3; a++) v += Jdi[a * 2 + k] * Jqi[a * m + l];
          Bi[k * m + l] = v;
        }
      }
      double det = A[0] * A[3] - A[1] * A[2], *Ai = Ainv + 4 * i;
      Ai[0] = A[3] / det; Ai[1] = -A[1] / det; Ai[2] = -A[2] / det; Ai[3] = A[0] / det;
      double AB[2 * FIT_M], Ag[2];
      for (int k = 0; k < 2; k++) {
        Ag[k] = Ai[k * 2] * gdi[0] + Ai[k * 2 + 1] * gdi[1];
        for (int l = 0; l < m; l++) AB[k * m + l] = Ai[k * 2] * Bi[l] + Ai[k * 2 + 1] * Bi[m + l];
      }
      for (int a = 0; a < m; a++) {
        double ga = 0;
        for (int c = 0; c < 3; c++) ga += Jqi[c * m + a] * ri[c];
        g[a] += ga - (Bi[a] * Ag[0] + Bi[m + a] * Ag[1]);
        for (int b = a; b < m; b++)  /* H is symmetric: the upper triangle, mirrored below */
          H[a * m + b] -= Bi[a] * AB[b] + Bi[m + a] * AB[m + b];
      }
      for (int c = 0; c < 3; c++)  /* + Jq^T Jq over the non-zeros of each output row */
        for (int ka = 0; ka < fit_jp_count[c]; ka++)
          for (int kb = ka; kb < fit_jp_count[c]; kb++) {
            int a = fit_jp_cols[c][ka], b = fit_jp_cols[c][kb];
            double h = Jqi[c * m + a] * Jqi[c * m + b];
            if (a <= b) H[a * m + b] += h; else H[b * m + a] += h;
          }
    }
    for (int a = 0; a < m; a++) for (int b = 0; b < a; b++) H[a * m + b] = H[b * m + a];
    for (int a = 0; a < m; a++) {
      if (it == 1 && !(H[a * m + a] > 1e-300)) return 3;
      dH[a] = sqrt(H[a * m + a] > 1e-300 ? H[a * m + a] : 1e-300);
    }
    double new_cost;
    double rdH[FIT_M];
    for (int a = 0; a < m; a++) rdH[a] = 1.0 / dH[a];
    for (;;) {  /* Levenberg-Marquardt: damp until the cost does not rise */
      for (int a = 0; a < m; a++) {
        for (int b = 0; b < m; b++) Hs[a * m + b] = H[a * m + b] * (rdH[a] * rdH[b]) + (a == b ? lam : 0);
        dp[a] = -g[a] * rdH[a];
      }
      if (!fit_cholesky(Hs, m)) return 2;
      fit_chol_solve(Hs, m, dp);
      for (int a = 0; a < m; a++) { dp[a] *= rdH[a]; p_new[a] = p[a] + dp[a]; }
      for (int i = 0; i < n; i++) {
        double *Bi = B + 2 * m * i, *Ai = Ainv + 4 * i, *Ei = E + 6 * i, v[2], dd[2], s = 0;
        for (int k = 0; k < 2; k++) {
          v[k] = gd[2 * i + k];
          for (int l = 0; l < m; l++) v[k] += Bi[k * m + l] * dp[l];
        }
        dd[0] = -(Ai[0] * v[0] + Ai[1] * v[1]);
        dd[1] = -(Ai[2] * v[0] + Ai[3] * v[1]);
        for (int a = 0; a < 3; a++) {
          u_new[3 * i + a] = u[3 * i + a] + Ei[a * 2] * dd[0] + Ei[a * 2 + 1] * dd[1];
          s += u_new[3 * i + a] * u_new[3 * i + a];
        }
        s = sqrt(s);
        for (int a = 0; a < 3; a++) u_new[3 * i + a] /= s;
      }
      new_cost = fit_cost(n, N, rho, sig, aux, p_new, u_new, Nm, Ju, Jp, iw, w);
      if (new_cost <= cost * (1 + 1e-12) || lam > 1e8) {
        lam = lam > 1e-6 ? lam / 10 : 0.0;
        break;
      }
      lam = 10 * lam > 1e-3 ? 10 * lam : 1e-3;
    }
    double decrement = 0, step = 0;
    for (int a = 0; a < m; a++) {
      decrement -= g[a] * dp[a];
      double sa = fabs(dp[a]) * sqrt(H[a * m + a]);
      if (sa > step) step = sa;
    }
    memcpy(p, p_new, sizeof(double) * m);
    memcpy(u, u_new, sizeof(double) * 3 * n);
    double big = cost > 1e-30 ? cost : 1e-30;
    done = fabs(cost - new_cost) <= tol * big || step < 1e-6 || decrement <= 1e-12 * (cost > 1 ? cost : 1);
    cost = new_cost;
  }
  *iters = it - 1;
  *cost_out = cost;
  /* covariance from the last linearisation: inv(H scaled) / outer(dH) */
  for (int a = 0; a < m; a++) for (int b = 0; b < m; b++) Hs[a * m + b] = H[a * m + b] / (dH[a] * dH[b]);
  if (!fit_cholesky(Hs, m)) return 2;
  fit_chol_inverse(Hs, m, cov);
  for (int a = 0; a < m; a++) for (int b = 0; b < m; b++) cov[a * m + b] /= dH[a] * dH[b];
  return done ? 0 : 1;
}

CASADI_SYMBOL_EXPORT int MODEL_FIT(int n_sets, int n, const double *N, const double *rho, const double *sig,
                                   const double *aux, const double *p0, int max_iter, double tol, double *p,
                                   double *cov, double *u, double *cost, int *iters, int *status) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  MODEL_WORK(&sz_arg, &sz_res, &sz_iw, &sz_w);
  int failed = 0;
  /* sets are independent: one work area per thread (OpenMP where the compiler has it) */
#pragma omp parallel reduction(+:failed)
  {
    casadi_int *iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
    double *w = malloc(sizeof(double) * (sz_w + 1));
    double *buf = malloc(sizeof(double) * (size_t) n * (6 + 3 * FIT_M + 4 + 2 * FIT_M + 2 + 6 + 3 + 3));
    if (!iw || !w || !buf) failed++;
    else {
#pragma omp for schedule(static)
      for (int s = 0; s < n_sets; s++)
        status[s] = fit_one(n, N + 3 * n * s, rho + n * s, sig + 3 * n * s, aux + FIT_NAUX * n * s, p0 + FIT_M * s,
                            max_iter, tol, p + FIT_M * s, cov + FIT_M * FIT_M * s, u + 3 * n * s, cost + s, iters + s,
                            buf, iw, w);
    }
    free(iw); free(w); free(buf);
  }
  return failed ? -1 : 0;
}
