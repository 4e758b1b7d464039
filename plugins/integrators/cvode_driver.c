/* SUNDIALS CVODE called from C on a CasADi-generated right-hand side y' = f(t, y)
 * (the sundials-cvode-c integrator plugin, plugins/integrators/cvode_c.py).
 *
 * One call, wb_cvode_solve, integrates over the whole output grid: no Python and no
 * CasADi runs between steps. The right-hand side is the generated C function itself,
 * called through CasADi's C calling convention with work arrays of the sizes its
 * <name>_work function reports (checked by the caller).
 *
 * SUNDIALS ships here as shared libraries without headers (scikit-sundae's wheel), so the
 * few declarations used are written below, as the SUNDIALS 7 documentation states them
 * (https://sundials.readthedocs.io/en/latest/cvode/Usage/index.html; sundials_context.h,
 * nvector_serial.h, sunmatrix_dense.h, sunlinsol_dense.h, sunnonlinsol_fixedpoint.h,
 * cvode.h, cvode_ls.h), for a build with sunrealtype double and sunindextype int32
 * (scikit-sundae's c_config.pxi). They are only pointers, ints, longs and doubles.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef double sunrealtype;
typedef int sunindextype;
typedef int SUNErrCode;
typedef int SUNComm; /* SUNDIALS without MPI */
typedef struct _SUNContext* SUNContext;
typedef struct _generic_N_Vector* N_Vector;
typedef struct _generic_SUNMatrix* SUNMatrix;
typedef struct _generic_SUNLinearSolver* SUNLinearSolver;
typedef struct _generic_SUNNonlinearSolver* SUNNonlinearSolver;
typedef int (*CVRhsFn)(sunrealtype t, N_Vector y, N_Vector ydot, void* user_data);
typedef void (*SUNErrHandlerFn)(int line, const char* func, const char* file,
                                const char* msg, SUNErrCode code, void* data,
                                SUNContext sunctx);

#define SUN_COMM_NULL 0
#define CV_ADAMS 1
#define CV_BDF 2
#define CV_NORMAL 1

SUNErrCode SUNContext_Create(SUNComm comm, SUNContext* sunctx);
SUNErrCode SUNContext_Free(SUNContext* sunctx);
SUNErrCode SUNContext_ClearErrHandlers(SUNContext sunctx);
SUNErrCode SUNContext_PushErrHandler(SUNContext sunctx, SUNErrHandlerFn fn, void* data);
N_Vector N_VNew_Serial(sunindextype length, SUNContext sunctx);
sunrealtype* N_VGetArrayPointer(N_Vector v);
void N_VDestroy(N_Vector v);
SUNMatrix SUNDenseMatrix(sunindextype rows, sunindextype columns, SUNContext sunctx);
void SUNMatDestroy(SUNMatrix A);
SUNLinearSolver SUNLinSol_Dense(N_Vector y, SUNMatrix A, SUNContext sunctx);
SUNErrCode SUNLinSolFree(SUNLinearSolver LS);
SUNNonlinearSolver SUNNonlinSol_FixedPoint(N_Vector y, int m, SUNContext sunctx);
SUNErrCode SUNNonlinSolFree(SUNNonlinearSolver NLS);
void* CVodeCreate(int lmm, SUNContext sunctx);
int CVodeInit(void* cvode_mem, CVRhsFn f, sunrealtype t0, N_Vector y0);
int CVodeSStolerances(void* cvode_mem, sunrealtype reltol, sunrealtype abstol);
int CVodeSetUserData(void* cvode_mem, void* user_data);
int CVodeSetMaxNumSteps(void* cvode_mem, long int mxsteps);
int CVodeSetMaxStep(void* cvode_mem, sunrealtype hmax);
int CVodeSetMaxOrd(void* cvode_mem, int maxord);
int CVodeSetMaxHnilWarns(void* cvode_mem, int mxhnil);
int CVodeSetNonlinearSolver(void* cvode_mem, SUNNonlinearSolver NLS);
int CVodeSetLinearSolver(void* cvode_mem, SUNLinearSolver LS, SUNMatrix A);
int CVode(void* cvode_mem, sunrealtype tout, N_Vector yout, sunrealtype* tret, int itask);
int CVodeGetNumSteps(void* cvode_mem, long int* value);
int CVodeGetNumRhsEvals(void* cvode_mem, long int* value);
int CVodeGetNumLinRhsEvals(void* cvode_mem, long int* value);
int CVodeGetNumErrTestFails(void* cvode_mem, long int* value);
int CVodeGetNumNonlinSolvIters(void* cvode_mem, long int* value);
int CVodeGetNumNonlinSolvConvFails(void* cvode_mem, long int* value);
int CVodeGetNumLinSolvSetups(void* cvode_mem, long int* value);
int CVodeGetNumJacEvals(void* cvode_mem, long int* value);
int CVodeGetCurrentTime(void* cvode_mem, sunrealtype* tcur);
char* CVodeGetReturnFlagName(long int flag);
void CVodeFree(void** cvode_mem);

/* CasADi's generated function: int f(const casadi_real** arg, casadi_real** res,
   casadi_int* iw, casadi_real* w, int mem), casadi_int = long long int */
typedef int (*casadi_function)(const double** arg, double** res, long long* iw, double* w,
                               int mem);

typedef struct {
  long long steps, rhs_evals, lin_rhs_evals, err_test_fails, nonlin_iters,
      nonlin_conv_fails, lin_setups, jac_evals, rhs_calls;
  double t_reached;
  int flag;        /* CVODE's last return flag (< 0: the failure) */
  int reached;     /* output times reached, the start included */
  char flag_name[32];
  char message[512]; /* SUNDIALS' own message of the failure, if any */
} wb_cvode_result;

typedef struct {
  casadi_function f;
  int n;
  const double** arg;
  double** res;
  long long* iw;
  double* w;
  long long calls;
  int failed;      /* 1: f returned an error, 2: a value was NaN or infinite */
  double failed_t; /* where */
} rhs_data;

/* y' = f(t, y); an error of f or a non-finite value stops the integration (CVODE's
   CV_UNREC_RHSFUNC_ERR), as the other integrators stop at a NaN: a shorter step would
   reach the same singular state, after thousands of steps of 1e-17 s. */
static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user_data) {
  rhs_data* data = (rhs_data*)user_data;
  double* out = N_VGetArrayPointer(ydot);
  int i;
  data->calls++;
  data->arg[0] = &t;
  data->arg[1] = N_VGetArrayPointer(y);
  data->res[0] = out;
  if (data->f(data->arg, data->res, data->iw, data->w, 0)) {
    data->failed = 1, data->failed_t = t;
    return -1;
  }
  for (i = 0; i < data->n; ++i)
    if (!isfinite(out[i])) {
      data->failed = 2, data->failed_t = t;
      return -1;
    }
  return 0;
}

static void keep_message(int line, const char* func, const char* file, const char* msg,
                         SUNErrCode code, void* user_data, SUNContext sunctx) {
  wb_cvode_result* result = (wb_cvode_result*)user_data;
  (void)line, (void)file, (void)code, (void)sunctx;
  if (msg == NULL) return;
  strncpy(result->message, msg, sizeof(result->message) - 1);
  result->message[sizeof(result->message) - 1] = '\0';
  (void)func;
}

/* Integrate y' = f(t, y) from (times[0], y0) to each times[k] (CV_NORMAL), writing the
   state at times[k] to y_out[k * n ...]. method: CV_ADAMS (1) or CV_BDF (2); newton: 0 for
   fixed-point iteration, 1 for Newton with a dense linear solver and CVODE's
   difference-quotient Jacobian. max_steps: steps towards each output time; max_step: 0
   for none; max_order: 0 for the method's highest. Returns the number of output times
   reached (>= 1); result holds the statistics (read from CVODE after a failure too; -1
   where there was no CVODE memory to read them from) and, on a failure, CVODE's flag. */
int wb_cvode_solve(casadi_function f, int n, long long sz_arg, long long sz_res,
                   long long sz_iw, long long sz_w, const double* times, int n_times,
                   const double* y0, double* y_out, int method, int newton, double rtol,
                   double atol, long max_steps, double max_step, int max_order,
                   wb_cvode_result* result) {
  SUNContext sunctx = NULL;
  N_Vector y = NULL;
  SUNMatrix A = NULL;
  SUNLinearSolver LS = NULL;
  SUNNonlinearSolver NLS = NULL;
  void* mem = NULL;
  rhs_data data;
  long int count;
  sunrealtype t = times[0];
  int k, flag = 0;

  memset(result, 0, sizeof(*result));
  /* -1: not read (no CVODE memory to read it from); no linear solver: none of its work */
  result->steps = result->rhs_evals = result->err_test_fails = result->nonlin_iters = -1;
  result->nonlin_conv_fails = -1;
  result->lin_rhs_evals = result->lin_setups = result->jac_evals = newton ? -1 : 0;
  result->reached = 1;
  result->t_reached = times[0];
  memcpy(y_out, y0, sizeof(double) * (size_t)n);
  memset(&data, 0, sizeof(data));
  data.f = f, data.n = n;
  data.arg = (const double**)calloc((size_t)(sz_arg > 2 ? sz_arg : 2), sizeof(double*));
  data.res = (double**)calloc((size_t)(sz_res > 1 ? sz_res : 1), sizeof(double*));
  data.iw = (long long*)calloc((size_t)(sz_iw > 1 ? sz_iw : 1), sizeof(long long));
  data.w = (double*)calloc((size_t)(sz_w > 1 ? sz_w : 1), sizeof(double));
  if (!data.arg || !data.res || !data.iw || !data.w) {
    flag = -20; /* CV_MEM_FAIL */
    goto done;
  }
  if (SUNContext_Create(SUN_COMM_NULL, &sunctx) != 0) {
    flag = -32; /* CV_CONTEXT_ERR */
    goto done;
  }
  SUNContext_ClearErrHandlers(sunctx); /* no printing to stderr: the message is kept */
  SUNContext_PushErrHandler(sunctx, keep_message, result);
  y = N_VNew_Serial(n, sunctx);
  mem = CVodeCreate(method, sunctx);
  if (y == NULL || mem == NULL) {
    flag = -20;
    goto done;
  }
  memcpy(N_VGetArrayPointer(y), y0, sizeof(double) * (size_t)n);
  if ((flag = CVodeInit(mem, rhs, times[0], y)) < 0) goto done;
  if ((flag = CVodeSStolerances(mem, rtol, atol)) < 0) goto done;
  if ((flag = CVodeSetUserData(mem, &data)) < 0) goto done;
  if ((flag = CVodeSetMaxNumSteps(mem, max_steps)) < 0) goto done;
  if (max_step > 0 && (flag = CVodeSetMaxStep(mem, max_step)) < 0) goto done;
  if (max_order > 0 && (flag = CVodeSetMaxOrd(mem, max_order)) < 0) goto done;
  /* no "t + h = t" warnings: SUNDIALS' logger would print them to stdout */
  if ((flag = CVodeSetMaxHnilWarns(mem, -1)) < 0) goto done;
  if (newton) {
    A = SUNDenseMatrix(n, n, sunctx);
    LS = A ? SUNLinSol_Dense(y, A, sunctx) : NULL;
    if (LS == NULL) {
      flag = -20;
      goto done;
    }
    if ((flag = CVodeSetLinearSolver(mem, LS, A)) < 0) goto done;
  } else {
    NLS = SUNNonlinSol_FixedPoint(y, 0, sunctx);
    if (NLS == NULL) {
      flag = -20;
      goto done;
    }
    if ((flag = CVodeSetNonlinearSolver(mem, NLS)) < 0) goto done;
  }
  for (k = 1; k < n_times; ++k) {
    flag = CVode(mem, times[k], y, &t, CV_NORMAL);
    if (flag < 0) break;
    memcpy(y_out + (size_t)k * (size_t)n, N_VGetArrayPointer(y), sizeof(double) * (size_t)n);
    result->reached = k + 1;
  }
  result->t_reached = times[result->reached - 1];
  if (flag < 0) CVodeGetCurrentTime(mem, &result->t_reached);

done:
  if (mem != NULL) {
    if (CVodeGetNumSteps(mem, &count) == 0) result->steps = count;
    if (CVodeGetNumRhsEvals(mem, &count) == 0) result->rhs_evals = count;
    if (CVodeGetNumErrTestFails(mem, &count) == 0) result->err_test_fails = count;
    if (CVodeGetNumNonlinSolvIters(mem, &count) == 0) result->nonlin_iters = count;
    if (CVodeGetNumNonlinSolvConvFails(mem, &count) == 0) result->nonlin_conv_fails = count;
    if (newton) {
      if (CVodeGetNumLinRhsEvals(mem, &count) == 0) result->lin_rhs_evals = count;
      if (CVodeGetNumLinSolvSetups(mem, &count) == 0) result->lin_setups = count;
      if (CVodeGetNumJacEvals(mem, &count) == 0) result->jac_evals = count;
    }
  }
  result->rhs_calls = data.calls;
  result->flag = flag < 0 ? flag : 0;
  if (flag < 0 && data.failed)
    snprintf(result->message, sizeof(result->message), "the right-hand side %s at t = %.10g",
             data.failed == 1 ? "returned an error" : "was NaN or infinite", data.failed_t);
  if (flag < 0) {
    char* name = CVodeGetReturnFlagName(flag);
    if (name != NULL) {
      strncpy(result->flag_name, name, sizeof(result->flag_name) - 1);
      free(name);
    }
  }
  CVodeFree(&mem);
  if (NLS != NULL) SUNNonlinSolFree(NLS);
  if (LS != NULL) SUNLinSolFree(LS);
  if (A != NULL) SUNMatDestroy(A);
  if (y != NULL) N_VDestroy(y);
  if (sunctx != NULL) SUNContext_Free(&sunctx);
  free(data.arg), free(data.res), free(data.iw), free(data.w);
  return result->reached;
}
