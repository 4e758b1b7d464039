// pinocchio::aba as a CasADi external function for the per-call benchmark's like-for-like
// line (benchmarks/peers_pyperf.py): y = [q; v] in Pinocchio's coordinates (nq + nv, any
// joints) -> [v; pinocchio::aba(q, v, 0)] (2 nv), so that both sides are called the same
// way, through CasADi's buffer call. The model is read once by aba_call_load from
// Pinocchio's text serialization (pin.Model.saveToText). Built by benchmarks/anchor.py.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <vector>

typedef long long int casadi_int;

namespace {
pinocchio::Model model;
pinocchio::Data data;
Eigen::VectorXd tau;
std::vector<casadi_int> sparsity_t, sparsity_y, sparsity_out;

std::vector<casadi_int> column(casadi_int n) {
  std::vector<casadi_int> s = {n, 1, 0, n};
  for (casadi_int i = 0; i < n; ++i) s.push_back(i);
  return s;
}
}  // namespace

extern "C" {

// Reads the model; returns nv, or -1.
int aba_call_load(const char* path) {
  try {
    model.loadFromText(path);
  } catch (...) {
    return -1;
  }
  data = pinocchio::Data(model);
  tau = Eigen::VectorXd::Zero(model.nv);
  sparsity_t = {1, 1, 0, 1, 0};
  sparsity_y = column(model.nq + model.nv);
  sparsity_out = column(2 * model.nv);
  return model.nv;
}

casadi_int aba_call_n_in(void) { return 2; }
casadi_int aba_call_n_out(void) { return 1; }
const char* aba_call_name_in(casadi_int i) { return i == 0 ? "t" : "y"; }
const char* aba_call_name_out(casadi_int i) { return "v_vdot"; }
const casadi_int* aba_call_sparsity_in(casadi_int i) {
  return i == 0 ? sparsity_t.data() : sparsity_y.data();
}
const casadi_int* aba_call_sparsity_out(casadi_int i) { return sparsity_out.data(); }
int aba_call_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  *sz_arg = 2, *sz_res = 1, *sz_iw = 0, *sz_w = 0;
  return 0;
}

int aba_call(const double** arg, double** res, casadi_int* iw, double* w, int mem) {
  const int nq = model.nq, nv = model.nv;
  if (!res[0]) return 0;
  Eigen::Map<const Eigen::VectorXd> q(arg[1], nq), v(arg[1] + nq, nv);
  pinocchio::aba(model, data, q, v, tau);
  Eigen::Map<Eigen::VectorXd> out(res[0], 2 * nv);
  out.head(nv) = v;
  out.tail(nv) = data.ddq;
  return 0;
}
}
