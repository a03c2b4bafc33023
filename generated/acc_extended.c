/* How to prefix internal symbols */
#ifdef CASADI_CODEGEN_PREFIX
  #define CASADI_NAMESPACE_CONCAT(NS, ID) _CASADI_NAMESPACE_CONCAT(NS, ID)
  #define _CASADI_NAMESPACE_CONCAT(NS, ID) NS ## ID
  #define CASADI_PREFIX(ID) CASADI_NAMESPACE_CONCAT(CODEGEN_PREFIX, ID)
#else
  #define CASADI_PREFIX(ID) acc_extended_ ## ID
#endif

#include <math.h>

#ifndef casadi_real
#define casadi_real double
#endif

#ifndef casadi_int
#define casadi_int long long int
#endif

/* Add prefix to internal symbols */
#define casadi_f0 CASADI_PREFIX(f0)
#define casadi_s0 CASADI_PREFIX(s0)
#define casadi_s1 CASADI_PREFIX(s1)
#define casadi_s2 CASADI_PREFIX(s2)
#define casadi_s3 CASADI_PREFIX(s3)
#define casadi_sq CASADI_PREFIX(sq)

/* Symbol visibility in DLLs */
#ifndef CASADI_SYMBOL_EXPORT
  #if defined(_WIN32) || defined(__WIN32__) || defined(__CYGWIN__)
    #if defined(STATIC_LINKED)
      #define CASADI_SYMBOL_EXPORT
    #else
      #define CASADI_SYMBOL_EXPORT __declspec(dllexport)
    #endif
  #elif defined(__GNUC__) && defined(GCC_HASCLASSVISIBILITY)
    #define CASADI_SYMBOL_EXPORT __attribute__ ((visibility ("default")))
  #else
    #define CASADI_SYMBOL_EXPORT
  #endif
#endif

casadi_real casadi_sq(casadi_real x) { return x*x;}

/* Configuration this file was compiled with */
CASADI_SYMBOL_EXPORT void acc_extended_casadi_version(int* major, int* minor, int* patch) {
  *major = 3;
  *minor = 8;
  *patch = 2;
}
CASADI_SYMBOL_EXPORT int acc_extended_casadi_int_size(void) { return (int) sizeof(casadi_int); }
CASADI_SYMBOL_EXPORT int acc_extended_casadi_real_size(void) { return (int) sizeof(casadi_real); }

static const casadi_int casadi_s0[3] = {3, 1, 1};
static const casadi_int casadi_s1[3] = {12, 1, 1};
static const casadi_int casadi_s2[13] = 
  {3, 3, 0, 3, 6, 7, 0, 1,
  2, 0, 1, 2, 2};
static const casadi_int casadi_s3[27] = 
  {3, 12, 0, 1, 2, 3, 4, 5,
  6, 7, 8, 9, 10, 11, 12, 0,
  1, 2, 1, 2, 2, 0, 1, 2,
  2, 0, 1};

/* simucal_acc_extended:(u[3],p[12],aux[3])->(N[3],N_u[3x3,7nz],N_p[3x12,12nz]) */
static int casadi_f0(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {
  casadi_real a00, a01, a02, a03, a04, a05, a06, a07, a08, a09, a10, a11;
  casadi_real a12, a13, a14, a15;
  a00=arg[1]? arg[1][10] : 0;
  a01=arg[0]? arg[0][0] : 0;
  a02=(a00*a01);
  a03=arg[0]? arg[0][1] : 0;
  a04=(a02*a03);
  a05=arg[1]? arg[1][6] : 0;
  a04=(a04+a05);
  a05=arg[1]? arg[1][0] : 0;
  a06=(a05*a01);
  a04=(a04+a06);
  a04=(a04+a01);
  if (res[0]!=0) res[0][0]=a04;
  a04=arg[1]? arg[1][7] : 0;
  a06=arg[1]? arg[1][11] : 0;
  a07=arg[2]? arg[2][1] : 0;
  a06=(a06*a07);
  a04=(a04+a06);
  a06=arg[1]? arg[1][1] : 0;
  a08=(a06*a03);
  a04=(a04+a08);
  a08=arg[1]? arg[1][3] : 0;
  a09=(a01*a08);
  a04=(a04+a09);
  a04=(a04+a03);
  if (res[0]!=0) res[0][1]=a04;
  a04=arg[1]? arg[1][9] : 0;
  a09=arg[0]? arg[0][2] : 0;
  a10=casadi_sq(a09);
  a11=(a04*a10);
  a12=arg[1]? arg[1][8] : 0;
  a11=(a11+a12);
  a12=arg[1]? arg[1][2] : 0;
  a13=(a12*a09);
  a11=(a11+a13);
  a13=arg[1]? arg[1][4] : 0;
  a14=(a01*a13);
  a11=(a11+a14);
  a14=arg[1]? arg[1][5] : 0;
  a15=(a03*a14);
  a11=(a11+a15);
  a11=(a11+a09);
  if (res[0]!=0) res[0][2]=a11;
  a00=(a03*a00);
  a00=(a00+a05);
  a05=1.;
  a00=(a00+a05);
  if (res[1]!=0) res[1][0]=a00;
  if (res[1]!=0) res[1][1]=a08;
  if (res[1]!=0) res[1][2]=a13;
  if (res[1]!=0) res[1][3]=a02;
  a06=(a06+a05);
  if (res[1]!=0) res[1][4]=a06;
  if (res[1]!=0) res[1][5]=a14;
  a14=(2.*a09);
  a04=(a04*a14);
  a04=(a04+a12);
  a04=(a04+a05);
  if (res[1]!=0) res[1][6]=a04;
  if (res[2]!=0) res[2][0]=a01;
  if (res[2]!=0) res[2][1]=a03;
  if (res[2]!=0) res[2][2]=a09;
  if (res[2]!=0) res[2][3]=a01;
  if (res[2]!=0) res[2][4]=a01;
  if (res[2]!=0) res[2][5]=a03;
  if (res[2]!=0) res[2][6]=a05;
  if (res[2]!=0) res[2][7]=a05;
  if (res[2]!=0) res[2][8]=a05;
  if (res[2]!=0) res[2][9]=a10;
  a01=(a01*a03);
  if (res[2]!=0) res[2][10]=a01;
  if (res[2]!=0) res[2][11]=a07;
  return 0;
}

CASADI_SYMBOL_EXPORT int simucal_acc_extended(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem){
  return casadi_f0(arg, res, iw, w, mem);
}

CASADI_SYMBOL_EXPORT int simucal_acc_extended_checkout(void) {
  return 0;
}

CASADI_SYMBOL_EXPORT void simucal_acc_extended_release(int mem) {
}

CASADI_SYMBOL_EXPORT void simucal_acc_extended_incref(void) {
}

CASADI_SYMBOL_EXPORT void simucal_acc_extended_decref(void) {
}

CASADI_SYMBOL_EXPORT casadi_int simucal_acc_extended_n_in(void) { return 3;}

CASADI_SYMBOL_EXPORT casadi_int simucal_acc_extended_n_out(void) { return 3;}

CASADI_SYMBOL_EXPORT casadi_real simucal_acc_extended_default_in(casadi_int i) {
  switch (i) {
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const char* simucal_acc_extended_name_in(casadi_int i) {
  switch (i) {
    case 0: return "u";
    case 1: return "p";
    case 2: return "aux";
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const char* simucal_acc_extended_name_out(casadi_int i) {
  switch (i) {
    case 0: return "N";
    case 1: return "N_u";
    case 2: return "N_p";
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const casadi_int* simucal_acc_extended_sparsity_in(casadi_int i) {
  switch (i) {
    case 0: return casadi_s0;
    case 1: return casadi_s1;
    case 2: return casadi_s0;
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const casadi_int* simucal_acc_extended_sparsity_out(casadi_int i) {
  switch (i) {
    case 0: return casadi_s0;
    case 1: return casadi_s2;
    case 2: return casadi_s3;
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT int simucal_acc_extended_work(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, casadi_int *sz_w) {
  if (sz_arg) *sz_arg = 3;
  if (sz_res) *sz_res = 3;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}

CASADI_SYMBOL_EXPORT int simucal_acc_extended_work_bytes(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, casadi_int *sz_w) {
  if (sz_arg) *sz_arg = 3*sizeof(const casadi_real*);
  if (sz_res) *sz_res = 3*sizeof(casadi_real*);
  if (sz_iw) *sz_iw = 0*sizeof(casadi_int);
  if (sz_w) *sz_w = 0*sizeof(casadi_real);
  return 0;
}


