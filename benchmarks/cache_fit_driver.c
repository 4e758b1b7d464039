/* Calls one CasADi-style C function (ours, or benchmarks/aba_call.cpp's pinocchio::aba)
 * a given number of times, for benchmarks/cache_fit.py to run under cachegrind:
 *   cache_fit_driver LIBRARY SYMBOL CALLS [MODEL_TEXT]
 * MODEL_TEXT: a pin.Model text file, read by aba_call_load first (the anchor only). */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

typedef long long casadi_int;
typedef int (*eval_t)(const double**, double**, casadi_int*, double*, int);
typedef int (*work_t)(casadi_int*, casadi_int*, casadi_int*, casadi_int*);
typedef const casadi_int* (*sparsity_t)(casadi_int);
typedef int (*load_t)(const char*);

static void* symbol(void* library, const char* name, const char* suffix) {
  char full[256];
  snprintf(full, sizeof full, "%s%s", name, suffix);
  void* found = dlsym(library, full);
  if (!found) {
    fprintf(stderr, "no symbol %s\n", full);
    exit(2);
  }
  return found;
}

int main(int argc, char** argv) {
  if (argc < 4) {
    fprintf(stderr, "usage: %s LIBRARY SYMBOL CALLS [MODEL_TEXT]\n", argv[0]);
    return 2;
  }
  void* library = dlopen(argv[1], RTLD_NOW);
  if (!library) {
    fprintf(stderr, "%s\n", dlerror());
    return 2;
  }
  const char* name = argv[2];
  long calls = atol(argv[3]);
  if (argc > 4 && ((load_t)symbol(library, "aba_call_load", ""))(argv[4]) < 0) return 2;
  eval_t function = (eval_t)symbol(library, name, "");
  casadi_int n_arg, n_res, n_iw, n_w;
  ((work_t)symbol(library, name, "_work"))(&n_arg, &n_res, &n_iw, &n_w);
  const casadi_int* y_shape = ((sparsity_t)symbol(library, name, "_sparsity_in"))(1);
  const casadi_int* out_shape = ((sparsity_t)symbol(library, name, "_sparsity_out"))(0);
  const double** arg = calloc(n_arg + 2, sizeof *arg);
  double** res = calloc(n_res + 1, sizeof *res);
  casadi_int* iw = calloc(n_iw + 1, sizeof *iw);
  double* w = calloc(n_w + 1, sizeof *w);
  long ny = y_shape[0] * y_shape[1];
  double t = 0.0, *y = calloc(ny, sizeof *y), *out = calloc(out_shape[0] * out_shape[1], sizeof *out);
  for (long i = 0; i < ny; i++) y[i] = 0.1 * ((i * 7919) % 13) - 0.6;  /* any state */
  arg[0] = &t;
  arg[1] = y;
  res[0] = out;
  double sum = 0.0;
  for (long k = 0; k < calls; k++) {
    function(arg, res, iw, w, 0);
    sum += out[ny / 2];
  }
  printf("%g\n", sum);  /* keeps the calls */
  return 0;
}
