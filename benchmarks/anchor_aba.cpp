// The all-compiled anchor's right-hand side: y = [q, v] -> [v, pinocchio::aba(q, v, 0)],
// as a CasADi external function (CasADi's C API), so that CasADi's CVODES calls it with
// no Python between steps. The model is read once by anchor_load from Pinocchio's own
// text serialization (pin.Model.saveToText). Built by benchmarks/anchor.py.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <vector>

typedef long long int casadi_int;

namespace {
pinocchio::Model model;
pinocchio::Data data;
Eigen::VectorXd tau;
std::vector<casadi_int> sparsity_t, sparsity_y;
}  // namespace

extern "C" {

// Reads the model; returns nv (nq must equal nv: revolute joints only), or -1.
int anchor_load(const char* path) {
  try {
    model.loadFromText(path);
  } catch (...) {
    return -1;
  }
  if (model.nq != model.nv) return -1;
  data = pinocchio::Data(model);
  tau = Eigen::VectorXd::Zero(model.nv);
  const casadi_int n = 2 * model.nv;
  sparsity_t = {1, 1, 0, 1, 0};
  sparsity_y = {n, 1, 0, n};
  for (casadi_int i = 0; i < n; ++i) sparsity_y.push_back(i);
  return model.nv;
}

casadi_int anchor_rhs_n_in(void) { return 2; }
casadi_int anchor_rhs_n_out(void) { return 1; }
const char* anchor_rhs_name_in(casadi_int i) { return i == 0 ? "t" : "y"; }
const char* anchor_rhs_name_out(casadi_int i) { return "ydot"; }
const casadi_int* anchor_rhs_sparsity_in(casadi_int i) {
  return i == 0 ? sparsity_t.data() : sparsity_y.data();
}
const casadi_int* anchor_rhs_sparsity_out(casadi_int i) { return sparsity_y.data(); }
int anchor_rhs_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  *sz_arg = 2, *sz_res = 1, *sz_iw = 0, *sz_w = 0;
  return 0;
}

int anchor_rhs(const double** arg, double** res, casadi_int* iw, double* w, int mem) {
  const int nv = model.nv;
  if (!res[0]) return 0;
  Eigen::Map<const Eigen::VectorXd> q(arg[1], nv), v(arg[1] + nv, nv);
  pinocchio::aba(model, data, q, v, tau);
  Eigen::Map<Eigen::VectorXd> out(res[0], 2 * nv);
  out.head(nv) = v;
  out.tail(nv) = data.ddq;
  return 0;
}
}
