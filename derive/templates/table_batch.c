/* Batches of the table's kinematics (derive/table.py), for the Monte Carlo's simulated trials:
 * row i of each output from row i of the inputs (angles in rad), with the four table errors
 * (tilt_x, tilt_y, nonperp_om, nonperp_mi, rad) shared by the batch and the three angle errors
 * (d_gamma, d_alpha, d_beta, rad) per row: errors = TABLE_ERRORS, in that order. */
#include <math.h>
#include <stdlib.h>

static int table_batch(int (*f)(const casadi_real **, casadi_real **, casadi_int *, casadi_real *, int),
                       int (*work)(casadi_int *, casadi_int *, casadi_int *, casadi_int *), int n,
                       const double *gamma, const double *alpha, const double *beta, const double *table_err,
                       const double *angle_err, double *out) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  casadi_int *iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  double *w = malloc(sizeof(double) * (sz_w + 1));
  if (!iw || !w) { free(iw); free(w); return -1; }
  double trig[8];  /* cos and sin of each table error, once per batch */
  for (int k = 0; k < 4; k++) { trig[2 * k] = cos(table_err[k]); trig[2 * k + 1] = sin(table_err[k]); }
  for (int i = 0; i < n; i++) {
    const double *arg[5] = {gamma ? gamma + i : NULL, alpha + i, beta + i, trig, angle_err + 3 * i};
    double *res[1] = {out + 3 * i};
    if (gamma) f(arg, res, iw, w, 0);
    else f(arg + 1, res, iw, w, 0);  /* outer_axis_k does not depend on gamma */
  }
  free(iw); free(w);
  return 0;
}

/* f^k at rest (g), (n, 3) */
CASADI_SYMBOL_EXPORT int simucal_specific_force_k_batch(int n, const double *gamma, const double *alpha,
                                                        const double *beta, const double *table_err,
                                                        const double *angle_err, double *f_k) {
  return table_batch(simucal_specific_force_k, simucal_specific_force_k_work, n, gamma, alpha, beta, table_err,
                     angle_err, f_k);
}

/* the outer axis in k, (n, 3) */
CASADI_SYMBOL_EXPORT int simucal_outer_axis_k_batch(int n, const double *alpha, const double *beta,
                                                    const double *table_err, const double *angle_err, double *axis_k) {
  return table_batch(simucal_outer_axis_k, simucal_outer_axis_k_work, n, NULL, alpha, beta, table_err, angle_err,
                     axis_k);
}
