/* The whole exact norm fit of MODEL in one call (simucal.fit.norm_fit.fit_exact, written in C).
 *
 * For each of n_sets data sets of n rows: maximum likelihood on the norm principle,
 *     minimise sum_i |(N_i - h(rho_i u_i, p, aux_i)) / sigma_i|^2,  |u_i| = 1,
 * by Levenberg-Marquardt on p with a 2-D tangent step per direction u_i, the directions
 * eliminated by the Schur complement of their 2x2 blocks (rank one per row), the damping, the convergence
 * test and the covariance at the solution exactly as in fit_exact (so both give the same
 * numbers). h and its Jacobians come from the CasADi function above (dense outputs).
 *
 * Arrays are C-contiguous: N, sig, u (n_sets, n, 3); rho (n_sets, n); aux (n_sets, n, NAUX);
 * p0, p (n_sets, M); cov (n_sets, M, M) and cost (n_sets), or NULL where only the estimates are wanted. status per set: 0 converged, 1 not converged,
 * 2 singular (the plan leaves a combination unobservable), 3 a parameter without any input.
 */
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#else
static int omp_get_max_threads(void) { return 1; }
#endif

#define FIT_M MODEL_M
#define FIT_NAUX MODEL_NAUX
/* the parameters each output row depends on (the structural non-zeros of dN/dp, from derive) */
static const int fit_jp_count[3] = MODEL_JP_COUNT;
static const int fit_jp_cols[3][FIT_M] = MODEL_JP_COLS;

static int fit_eval(const double *u, const double *p, const double *aux, double *Nm, double *Ju, double *Jp,
                    casadi_int *iw, double *w) {
  const double *arg[3] = {u, p, aux};
  double *res[3] = {Nm, Ju, Jp};  /* Ju (3x3), Jp (3xM): column-major, dense; NULL: not wanted */
  return MODEL_EVAL(arg, res, iw, w, 0);
}

/* Cholesky of the SPD matrix A (k x k, row-major) in place (lower), its diagonal holding the
 * reciprocals 1/L_jj (products in the substitutions, not divisions); 0 if not positive definite. */
static int fit_cholesky(double *A, int k) {
  for (int j = 0; j < k; j++) {
    double s = A[j * k + j];
    for (int l = 0; l < j; l++) s -= A[j * k + l] * A[j * k + l];
    if (!(s > 0)) return 0;
    double r = 1.0 / sqrt(s);
    A[j * k + j] = r;
    for (int i = j + 1; i < k; i++) {
      double t = A[i * k + j];
      for (int l = 0; l < j; l++) t -= A[i * k + l] * A[j * k + l];
      A[i * k + j] = t * r;
    }
  }
  return 1;
}

static void fit_chol_solve(const double *L, int k, double *x) {
  for (int i = 0; i < k; i++) {
    double s = x[i];
    for (int l = 0; l < i; l++) s -= L[i * k + l] * x[l];
    x[i] = s * L[i * k + i];
  }
  for (int i = k - 1; i >= 0; i--) {
    double s = x[i];
    for (int l = i + 1; l < k; l++) s -= L[l * k + i] * x[l];
    x[i] = s * L[i * k + i];
  }
}

/* A^-1 = L^-T L^-1 from fit_cholesky's factor into inv (k x k, row-major, full): the triangular
 * inverse by forward substitution, then the product over its non-zeros. */
static void fit_chol_inverse(const double *L, int k, double *inv) {
  double Li[FIT_M * FIT_M];
  memset(Li, 0, sizeof(double) * k * k);
  for (int j = 0; j < k; j++) {
    Li[j * k + j] = L[j * k + j];
    for (int i = j + 1; i < k; i++) {
      double s = 0;
      for (int l = j; l < i; l++) s -= L[i * k + l] * Li[l * k + j];
      Li[i * k + j] = s * L[i * k + i];
    }
  }
  for (int a = 0; a < k; a++)
    for (int b = a; b < k; b++) {
      double s = 0;
      for (int l = b; l < k; l++) s += Li[l * k + a] * Li[l * k + b];
      inv[a * k + b] = inv[b * k + a] = s;
    }
}

/* The paper's linear fit as the start (dong2018 eq. 7-8 and 11-12): least squares of
 * psi(N_i) . K = rho_i^2 over the rows (normal equations, Jacobi-scaled: the columns differ by
 * orders of magnitude in deg/h), then the exact back-substitution p(K). Where it fails (singular,
 * or p(K) not finite) the start is p = 0, as montecarlo.fit_trials does in numpy. */
static void fit_start(int n, const double *N, const double *rho, const double *aux, double *p0, casadi_int *iw,
                      double *w) {
  const int m = FIT_M;
  double A[FIT_M * FIT_M], b[FIT_M], psi[FIT_M], d[FIT_M], K[FIT_M];
  memset(A, 0, sizeof A);
  memset(b, 0, sizeof b);
  for (int i = 0; i < n; i++) {
    const double *arg[2] = {N + 3 * i, aux + i * FIT_NAUX};
    double *res[1] = {psi};
    MODEL_REGRESSORS(arg, res, iw, w, 0);
    double r2 = rho[i] * rho[i];
    for (int a = 0; a < m; a++) {
      b[a] += psi[a] * r2;
      for (int c = 0; c <= a; c++) A[a * m + c] += psi[a] * psi[c];
    }
  }
  int ok = 1;
  for (int a = 0; a < m; a++) {
    ok = ok && A[a * m + a] > 0;
    d[a] = ok ? 1.0 / sqrt(A[a * m + a]) : 0;
  }
  for (int a = 0; a < m; a++) {
    for (int c = 0; c <= a; c++) A[a * m + c] *= d[a] * d[c];
    K[a] = b[a] * d[a];
  }
  ok = ok && fit_cholesky(A, m);
  if (ok) {
    fit_chol_solve(A, m, K);
    for (int a = 0; a < m; a++) K[a] *= d[a];
    const double *arg[1] = {K};
    double *res[1] = {p0};
    MODEL_PARAMS_OF_K(arg, res, iw, w, 0);
    for (int a = 0; a < m; a++) ok = ok && fabs(p0[a]) < HUGE_VAL;
  }
  if (!ok) memset(p0, 0, sizeof(double) * m);
}

static void fit_tangent(const double *u, double *E) {
  /* E (3x2, row-major): a basis of the plane normal to u, e1 = u x a, e2 = u x e1, with a the
   * axis u is furthest from (|e1| >= 0.43). Not normalised: a direction's step E dd is the same
   * in any basis of the plane, and fit_exact's orthonormal one gives the same numbers. */
  double e1[3];
  if (fabs(u[0]) < 0.9) { e1[0] = 0; e1[1] = u[2]; e1[2] = -u[1]; }  /* a = x */
  else { e1[0] = -u[2]; e1[1] = 0; e1[2] = u[0]; }                     /* a = y */
  double e2[3] = {u[1] * e1[2] - u[2] * e1[1], u[2] * e1[0] - u[0] * e1[2], u[0] * e1[1] - u[1] * e1[0]};
  for (int c = 0; c < 3; c++) { E[c * 2] = e1[c]; E[c * 2 + 1] = e2[c]; }
}

/* dp = -(Hsc + lam I)^-1 g, in the scaled variables (Hsc = H / outer(dH), lower triangle; rdH = 1/dH);
 * L receives the Cholesky factor. 0 where the system is singular. */
static int fit_damped_step(const double *Hsc, double lam, const double *g, const double *rdH, int m, double *L,
                           double *dp) {
  for (int a = 0; a < m; a++) {
    for (int b = 0; b <= a; b++) L[a * m + b] = Hsc[a * m + b] + (a == b ? lam : 0);
    dp[a] = -g[a] * rdH[a];
  }
  if (!fit_cholesky(L, m)) return 0;
  fit_chol_solve(L, m, dp);
  for (int a = 0; a < m; a++) dp[a] *= rdH[a];
  return 1;
}

/* The Gauss-Newton decrement -g . dp and the step's largest component in standard deviations
 * (|dp_a| sqrt(H_aa)): what the convergence tests read. */
static void fit_step_size(const double *g, const double *dp, const double *dH, int m, double *decrement,
                          double *step) {
  *decrement = *step = 0;
  for (int a = 0; a < m; a++) {
    *decrement -= g[a] * dp[a];
    double sa = fabs(dp[a]) * dH[a];
    if (sa > *step) *step = sa;
  }
}

static double fit_cost(int n, const double *N, const double *rho, const double *wsig, const double *aux,
                       const double *p, const double *u, casadi_int *iw, double *w) {
  double c = 0, Nm[3];
  for (int i = 0; i < n; i++) {
    double x[3] = {rho[i] * u[3 * i], rho[i] * u[3 * i + 1], rho[i] * u[3 * i + 2]};
    fit_eval(x, p, aux + i * FIT_NAUX, Nm, NULL, NULL, iw, w);  /* the output alone: no Jacobians stored */
    for (int c3 = 0; c3 < 3; c3++) {
      double r = (N[3 * i + c3] - Nm[c3]) * wsig[3 * i + c3];
      c += r * r;
    }
  }
  return c;
}

static void fit_normalise(double *v) {
  double s = 1.0 / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  v[0] *= s; v[1] *= s; v[2] *= s;
}

static int fit_one(int n, const double *N, const double *rho, const double *sig, const double *aux, const double *p0,
                   int max_iter, double tol, double *p, double *cov, double *u, double *cost_out, int *iters,
                   double *buf, casadi_int *iw, double *w) {
  const int m = FIT_M;
  double *Jd = buf, *Jq = Jd + 6 * n, *Ainv = Jq + 3 * m * n, *E = Ainv + 4 * n, *r = E + 6 * n;
  double *u_new = r + 3 * n, *wsig = u_new + 3 * n, *Qt = wsig + 3 * n, *Wt = Qt + FIT_M * n;
  double H[FIT_M * FIT_M], Hs[FIT_M * FIT_M], g[FIT_M], dH[FIT_M], dp[FIT_M], p_new[FIT_M];
  double Nm[3], Ju[9], Jp[3 * FIT_M];
  memcpy(p, p0, sizeof(double) * m);
  for (int k = 0; k < 3 * n; k++) wsig[k] = 1.0 / sig[k];  /* one division per component, products after */
  double adj[9], det = 0, b0[3];
  for (int i = 0; i < n; i++) {  /* initial directions: M u = N - b at u = 0 */
    /* M and b depend on p and the row's auxiliary inputs alone: recomputed where these change */
    if (i == 0 || memcmp(aux + i * FIT_NAUX, aux + (i - 1) * FIT_NAUX, sizeof(double) * FIT_NAUX)) {
      double z[3] = {0, 0, 0}, M3[9];
      fit_eval(z, p, aux + i * FIT_NAUX, Nm, Ju, Jp, iw, w);
      for (int a = 0; a < 3; a++) for (int c = 0; c < 3; c++) M3[a * 3 + c] = Ju[c * 3 + a];
      adj[0] = M3[4] * M3[8] - M3[5] * M3[7]; adj[1] = M3[2] * M3[7] - M3[1] * M3[8];
      adj[2] = M3[1] * M3[5] - M3[2] * M3[4]; adj[3] = M3[5] * M3[6] - M3[3] * M3[8];
      adj[4] = M3[0] * M3[8] - M3[2] * M3[6]; adj[5] = M3[2] * M3[3] - M3[0] * M3[5];
      adj[6] = M3[3] * M3[7] - M3[4] * M3[6]; adj[7] = M3[1] * M3[6] - M3[0] * M3[7];
      adj[8] = M3[0] * M3[4] - M3[1] * M3[3];
      det = M3[0] * adj[0] + M3[1] * adj[3] + M3[2] * adj[6];
      memcpy(b0, Nm, sizeof b0);
    }
    double y[3] = {N[3 * i] - b0[0], N[3 * i + 1] - b0[1], N[3 * i + 2] - b0[2]};
    /* adj y = det M^-1 y: times det, a positive factor det^2 that the normalisation removes */
    for (int a = 0; a < 3; a++) u[3 * i + a] = (adj[a * 3] * y[0] + adj[a * 3 + 1] * y[1] + adj[a * 3 + 2] * y[2]) * det;
    fit_normalise(u + 3 * i);
  }
  /* the cost at the current point: summed where each iteration forms the residuals */
  double cost = max_iter > 0 ? 0 : fit_cost(n, N, rho, wsig, aux, p, u, iw, w), lam = 0;
  int done = 0;
  *iters = 0;
  for (int it = 1; it <= max_iter && !done; it++) {
    *iters = it;
    memset(g, 0, sizeof g);
    cost = 0;
    for (int i = 0; i < n; i++) {  /* residual, Jacobian blocks, Schur complement */
      double x[3] = {rho[i] * u[3 * i], rho[i] * u[3 * i + 1], rho[i] * u[3 * i + 2]};
      fit_eval(x, p, aux + i * FIT_NAUX, Nm, Ju, Jp, iw, w);
      double *Ei = E + 6 * i, *Jdi = Jd + 6 * i, *Jqi = Jq + 3 * m * i, *ri = r + 3 * i;
      fit_tangent(u + 3 * i, Ei);
      for (int a = 0; a < 3; a++) {
        double ws = wsig[3 * i + a];
        ri[a] = (N[3 * i + a] - Nm[a]) * ws;
        for (int k = 0; k < 2; k++) {
          double v = 0;
          for (int b = 0; b < 3; b++) v += Ju[b * 3 + a] * Ei[b * 2 + k];
          Jdi[a * 2 + k] = -v * rho[i] * ws;
        }
        for (int ka = 0; ka < fit_jp_count[a]; ka++) {  /* read at these non-zeros only */
          int k = fit_jp_cols[a][ka];
          Jqi[a * m + k] = -Jp[k * 3 + a] * ws;
        }
      }
      cost += ri[0] * ri[0] + ri[1] * ri[1] + ri[2] * ri[2];
      double A[4] = {0, 0, 0, 0}, *Ai = Ainv + 4 * i;
      for (int k = 0; k < 2; k++) for (int l = k; l < 2; l++)
        for (int a = 0; a < 3; a++) A[k * 2 + l] += Jdi[a * 2 + k] * Jdi[a * 2 + l];
      double rdet = 1.0 / (A[0] * A[3] - A[1] * A[1]);
      Ai[0] = A[3] * rdet; Ai[1] = Ai[2] = -A[1] * rdet; Ai[3] = A[0] * rdet;
      /* the Schur complement of a direction's 2x2 block is rank one: with nv a normal to the
       * columns of Jd_i, I - Jd A^-1 Jd^T = nv nv^T / |nv|^2, so H += q q^T / |nv|^2 and
       * g += q (nv . r) / |nv|^2, q = Jq_i^T nv */
      double nv[3] = {Jdi[2] * Jdi[5] - Jdi[4] * Jdi[3], Jdi[4] * Jdi[1] - Jdi[0] * Jdi[5],
                      Jdi[0] * Jdi[3] - Jdi[2] * Jdi[1]};
      double rn2 = 1.0 / (nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
      double q[FIT_M], s = (nv[0] * ri[0] + nv[1] * ri[1] + nv[2] * ri[2]) * rn2;
      memset(q, 0, sizeof q);
      for (int c = 0; c < 3; c++)  /* over the non-zeros of each output row */
        for (int ka = 0; ka < fit_jp_count[c]; ka++) {
          int a = fit_jp_cols[c][ka];
          q[a] += nv[c] * Jqi[c * m + a];
        }
      for (int a = 0; a < m; a++) {
        g[a] += q[a] * s;
        Qt[a * n + i] = q[a];
        Wt[a * n + i] = q[a] * rn2;
      }
    }
    /* H = sum_i q_i q_i^T / |nv_i|^2: dot products over the rows, four partial sums (independent
     * chains), the upper triangle mirrored below */
    for (int a = 0; a < m; a++)
      for (int b = a; b < m; b++) {
        const double *wa = Wt + a * n, *qb = Qt + b * n;
        double h0 = 0, h1 = 0, h2 = 0, h3 = 0;
        int i = 0;
        for (; i + 3 < n; i += 4) {
          h0 += wa[i] * qb[i]; h1 += wa[i + 1] * qb[i + 1]; h2 += wa[i + 2] * qb[i + 2]; h3 += wa[i + 3] * qb[i + 3];
        }
        for (; i < n; i++) h0 += wa[i] * qb[i];
        H[a * m + b] = H[b * m + a] = (h0 + h1) + (h2 + h3);
      }
    for (int a = 0; a < m; a++) {
      if (it == 1 && !(H[a * m + a] > 1e-300)) return 3;
      dH[a] = sqrt(H[a * m + a] > 1e-300 ? H[a * m + a] : 1e-300);
    }
    double new_cost, rdH[FIT_M], Hsc[FIT_M * FIT_M], decrement, step;
    for (int a = 0; a < m; a++) rdH[a] = 1.0 / dH[a];
    for (int a = 0; a < m; a++) for (int b = 0; b <= a; b++) Hsc[a * m + b] = H[a * m + b] * (rdH[a] * rdH[b]);
    if (!fit_damped_step(Hsc, 0.0, g, rdH, m, Hs, dp)) return 2;
    fit_step_size(g, dp, dH, m, &decrement, &step);
    /* a Gauss-Newton step below 1e-6 of every parameter's standard deviation, or with its
     * decrement at round-off level, is the last: taken without the cost test, which a step that
     * small can fail on round-off alone (and did, with several damped retries per fit) */
    int last = step < 1e-6 || decrement <= 1e-12 * (cost > 1 ? cost : 1);
    for (;;) {  /* Levenberg-Marquardt: damp until the cost does not rise */
      if (lam > 0 && !last && !fit_damped_step(Hsc, lam, g, rdH, m, Hs, dp)) return 2;
      for (int a = 0; a < m; a++) p_new[a] = p[a] + dp[a];
      for (int i = 0; i < n; i++) {  /* each direction's step: -A^-1 Jd^T (r + Jq dp) */
        double *Jdi = Jd + 6 * i, *Jqi = Jq + 3 * m * i, *ri = r + 3 * i, *Ai = Ainv + 4 * i, *Ei = E + 6 * i;
        double y[3], v[2];
        for (int c = 0; c < 3; c++) {
          y[c] = ri[c];
          for (int ka = 0; ka < fit_jp_count[c]; ka++) y[c] += Jqi[c * m + fit_jp_cols[c][ka]] * dp[fit_jp_cols[c][ka]];
        }
        for (int k = 0; k < 2; k++) v[k] = Jdi[k] * y[0] + Jdi[2 + k] * y[1] + Jdi[4 + k] * y[2];
        double dd0 = -(Ai[0] * v[0] + Ai[1] * v[1]), dd1 = -(Ai[2] * v[0] + Ai[3] * v[1]);
        for (int a = 0; a < 3; a++) u_new[3 * i + a] = u[3 * i + a] + Ei[a * 2] * dd0 + Ei[a * 2 + 1] * dd1;
        fit_normalise(u_new + 3 * i);
      }
      /* the last step's cost only where the caller wants it */
      new_cost = last && !cost_out ? cost : fit_cost(n, N, rho, wsig, aux, p_new, u_new, iw, w);
      if (last || new_cost <= cost * (1 + 1e-12) || lam > 1e8) {
        lam = lam > 1e-6 ? lam / 10 : 0.0;
        break;
      }
      lam = 10 * lam > 1e-3 ? 10 * lam : 1e-3;
    }
    fit_step_size(g, dp, dH, m, &decrement, &step);
    memcpy(p, p_new, sizeof(double) * m);
    memcpy(u, u_new, sizeof(double) * 3 * n);
    double big = cost > 1e-30 ? cost : 1e-30;
    done = last || fabs(cost - new_cost) <= tol * big || step < 1e-6 || decrement <= 1e-12 * (cost > 1 ? cost : 1);
    cost = new_cost;
  }
  if (cost_out) *cost_out = cost;
  if (cov) {  /* covariance from the last linearisation: inv(H scaled) / outer(dH) */
    for (int a = 0; a < m; a++) for (int b = 0; b < m; b++) Hs[a * m + b] = H[a * m + b] / (dH[a] * dH[b]);
    if (!fit_cholesky(Hs, m)) return 2;
    fit_chol_inverse(Hs, m, cov);
    for (int a = 0; a < m; a++) for (int b = 0; b < m; b++) cov[a * m + b] /= dH[a] * dH[b];
  }
  return done ? 0 : 1;
}

/* p0 NULL: each set starts from the paper's linear fit (fit_start). n_threads: the OpenMP team
 * (1 where the caller runs batches on threads of its own; 0: OpenMP's default). */
CASADI_SYMBOL_EXPORT int MODEL_FIT(int n_sets, int n, const double *N, const double *rho, const double *sig,
                                   const double *aux, const double *p0, int max_iter, double tol, double *p,
                                   double *cov, double *u, double *cost, int *iters, int *status, int n_threads) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w, sz[4];
  MODEL_WORK(&sz_arg, &sz_res, &sz_iw, &sz_w);
  MODEL_REGRESSORS_WORK(&sz[0], &sz[1], &sz[2], &sz[3]);
  if (sz[2] > sz_iw) sz_iw = sz[2];
  if (sz[3] > sz_w) sz_w = sz[3];
  MODEL_PARAMS_OF_K_WORK(&sz[0], &sz[1], &sz[2], &sz[3]);
  if (sz[2] > sz_iw) sz_iw = sz[2];
  if (sz[3] > sz_w) sz_w = sz[3];
  int failed = 0;
  (void) n_threads;
  /* sets are independent: one work area per thread (OpenMP where the compiler has it; one set runs
   * here, as starting a team costs more than the fit) */
#pragma omp parallel reduction(+:failed) num_threads(n_threads > 0 ? n_threads : omp_get_max_threads()) if (n_sets > 1)
  {
    casadi_int *iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
    double *w = malloc(sizeof(double) * (sz_w + 1));
    double *buf = malloc(sizeof(double) * (size_t) n * (6 + 3 * FIT_M + 4 + 6 + 3 + 3 + 3 + 2 * FIT_M));
    if (!iw || !w || !buf) failed++;
    else {
#pragma omp for schedule(static)
      for (int s = 0; s < n_sets; s++) {
        double start[FIT_M];
        if (!p0) fit_start(n, N + 3 * n * s, rho + n * s, aux + FIT_NAUX * n * s, start, iw, w);
        status[s] = fit_one(n, N + 3 * n * s, rho + n * s, sig + 3 * n * s, aux + FIT_NAUX * n * s,
                            p0 ? p0 + FIT_M * s : start, max_iter, tol, p + FIT_M * s,
                            cov ? cov + FIT_M * FIT_M * s : NULL, u + 3 * n * s, cost ? cost + s : NULL, iters + s, buf, iw, w);
      }
    }
    free(iw); free(w); free(buf);
  }
  return failed ? -1 : 0;
}
