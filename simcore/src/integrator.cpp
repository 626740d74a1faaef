#include <rehearse/simcore/integrator.hpp>

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>

#include <chrono>
#include <cmath>

#include <dlfcn.h>

namespace rehearse::simcore {

struct Integrator::Solvers {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> cholmod;
  Eigen::SparseMatrix<double> K0, K, J;  // reused between steps (same pattern: no allocation)
  bool analysed = false;
  Eigen::Index patternNonZeros = -1;
  int analyses = 0;
};

namespace {
// OpenBLAS on one thread: factorising these sparse systems was 2x faster than on two here (DESIGN.md).
void singleThreadedBlas() {
  static const bool done = [] {
    using Fn = void (*)(int);
    auto fn = reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
    // OpenBLAS is loaded as a dependency of the reference BLAS name; look it up by its own name too.
    for (const char* lib : {"libopenblas.so.0", "libopenblas.so"})
      if (!fn)
        if (void* h = dlopen(lib, RTLD_NOLOAD | RTLD_LAZY)) fn = reinterpret_cast<Fn>(dlsym(h, "openblas_set_num_threads"));
    if (fn) fn(1);
    return true;
  }();
  (void)done;
}
}  // namespace

Integrator::Integrator(const FemModel& model, std::vector<int> fixedNodes, SimulationSettings settings)
    : model_(model), fixed_(model.nodeCount(), 0), settings_(settings), solvers_(std::make_unique<Solvers>()) {
  singleThreadedBlas();
  for (int n : fixedNodes) {
    if (n < 0 || n >= static_cast<int>(model.nodeCount()))
      throw MeshError("Fixed node " + std::to_string(n) + " does not exist (the mesh has " + std::to_string(model.nodeCount()) +
                      " nodes, numbered from 0).");
    fixed_[n] = 1;
  }
  const auto n = static_cast<Eigen::Index>(model.nodeCount());
  mass3_.resize(3 * n);
  gravityForce_.resize(3 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    mass3_.segment<3>(3 * i).setConstant(model.lumpedMass[i]);
    gravityForce_.segment<3>(3 * i) = model.lumpedMass[i] * settings.gravity;
  }
}

Integrator::~Integrator() = default;

int Integrator::symbolicAnalyses() const { return solvers_->analyses; }

SimulationState Integrator::initialState() const {
  SimulationState s;
  s.x = model_.restVector();
  s.v = Eigen::VectorXd::Zero(s.x.size());
  return s;
}

void Integrator::project(Eigen::VectorXd& r) const {
  for (std::size_t i = 0; i < fixed_.size(); ++i)
    if (fixed_[i]) r.segment<3>(3 * i).setZero();
}

void Integrator::projectMatrix(Eigen::SparseMatrix<double>& A) const {
  // Fixed dofs: identity rows and columns, keeping the sparsity pattern (so the analysis is reused).
  for (int k = 0; k < A.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, k); it; ++it)
      if (fixed_[it.row() / 3] || fixed_[it.col() / 3]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
}

bool Integrator::solveLinear(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y) {
  switch (settings_.solver) {
    case LinearSolverKind::Cholmod: {
      auto& s = *solvers_;
      if (!s.analysed || s.patternNonZeros != A.nonZeros()) {
        s.cholmod.analyzePattern(A);
        s.analysed = true;
        s.patternNonZeros = A.nonZeros();
        ++s.analyses;
      }
      s.cholmod.factorize(A);
      if (s.cholmod.info() != Eigen::Success) return false;
      y = s.cholmod.solve(b);
      return s.cholmod.info() == Eigen::Success && y.allFinite();
    }
    case LinearSolverKind::ConjugateGradient: {
      Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper, Eigen::IncompleteCholesky<double>> cg;
      cg.setMaxIterations(settings_.cgMaxIterations);
      cg.setTolerance(settings_.cgTolerance);
      cg.compute(A);
      if (cg.info() != Eigen::Success) return false;
      y = cg.solve(b);
      return y.allFinite();
    }
    default: {
      const Eigen::MatrixXd dense(A);
      Eigen::LDLT<Eigen::MatrixXd> ldlt(dense);
      if (ldlt.info() != Eigen::Success) return false;
      y = ldlt.solve(b);
      return y.allFinite();
    }
  }
}

double Integrator::totalEnergy(const SimulationState& s) const {
  const Eigen::VectorXd u = s.x - model_.restVector();
  return 0.5 * s.v.dot(mass3_.cwiseProduct(s.v)) + elasticEnergy(model_, s.x) - gravityForce_.dot(u);
}

StepReport Integrator::tryStep(SimulationState& state, double h) {
  StepReport rep;
  rep.timeStepUsed = h;
  const Eigen::VectorXd x0 = state.x, v0 = state.v;
  Eigen::VectorXd v = v0;
  project(v);
  const double alpha = settings_.rayleighMass, beta = settings_.rayleighStiffness;
  const Eigen::VectorXd Mv0 = mass3_.cwiseProduct(v0);
  // Rayleigh damping with the stiffness at the start of the step, so the Newton tangent below is exact.
  Eigen::SparseMatrix<double>& K0 = solvers_->K0;
  assembleStiffness(model_, x0, K0);
  auto residual = [&](const Eigen::VectorXd& vel) {
    const Eigen::VectorXd x = x0 + h * vel;
    Eigen::VectorXd r = (1 + h * alpha) * mass3_.cwiseProduct(vel) - Mv0 - h * (elasticForces(model_, x) + gravityForce_) +
                        h * beta * (K0 * vel);
    project(r);
    return r;
  };
  // Residual scale: momentum, load and internal forces at the start, with a floor (an acceleration of
  // 0.01 m/s^2 of the whole body) so a body at rest without load still has a meaningful tolerance.
  Eigen::VectorXd f0 = elasticForces(model_, x0);
  project(f0);
  const double scale = std::max({Mv0.norm(), h * gravityForce_.norm(), h * f0.norm(), h * 1e-2 * model_.lumpedMass.sum()});
  Eigen::VectorXd r = residual(v);
  double rn = r.norm();
  for (int it = 0; it < settings_.maxNewtonIterations; ++it) {
    if (!std::isfinite(rn)) break;
    if (rn <= settings_.tolerance * scale) {
      rep.ok = true;
      break;
    }
    // J = (1 + h alpha) M + h beta K0 + h^2 K(x)
    Eigen::SparseMatrix<double>& K = solvers_->K;
    assembleStiffness(model_, x0 + h * v, K);
    Eigen::SparseMatrix<double>& J = solvers_->J;
    if (J.nonZeros() != K.nonZeros()) J = model_.pattern;
    for (Eigen::Index i = 0; i < J.nonZeros(); ++i) J.valuePtr()[i] = h * beta * K0.valuePtr()[i] + h * h * K.valuePtr()[i];
    for (Eigen::Index i = 0; i < J.rows(); ++i) J.valuePtr()[model_.diagonalSlot[i]] += (1 + h * alpha) * mass3_[i];
    projectMatrix(J);
    Eigen::VectorXd dv;
    bool solved = solveLinear(J, -r, dv);
    // An indefinite tangent (large deformation of a nonlinear material): shift the diagonal until it factorises.
    double shift = 0;
    while (!solved && shift < 1e12) {
      shift = shift == 0 ? 1e-6 * J.diagonal().cwiseAbs().maxCoeff() : shift * 10;
      Eigen::SparseMatrix<double> Js = J;
      for (Eigen::Index i = 0; i < Js.rows(); ++i) Js.coeffRef(i, i) += shift;
      solved = solveLinear(Js, -r, dv);
    }
    if (!solved) {
      rep.status = "failed: the linear system could not be solved";
      break;
    }
    project(dv);
    double t = 1.0;
    Eigen::VectorXd vn = v + dv, rnew = residual(vn);
    if (settings_.lineSearch)
      while ((!rnew.allFinite() || rnew.norm() > rn) && t > 1.0 / 64) {
        t *= 0.5;
        vn = v + t * dv;
        rnew = residual(vn);
      }
    v = vn;
    ++rep.newtonIterations;
    r = rnew;
    rn = r.norm();
  }
  if (!rep.ok && std::isfinite(rn) && rn <= settings_.tolerance * scale) rep.ok = true;
  rep.residual = rn / scale;
  if (!std::isfinite(rn) || !v.allFinite()) {
    rep.ok = false;
    rep.status = "failed: the state became NaN or infinite";
  }
  if (rep.ok) {
    state.v = v;
    state.x = x0 + h * v;
    state.time += h;
    rep.status = "converged";
  } else if (rep.status.empty()) {
    rep.status = "not converged in " + std::to_string(settings_.maxNewtonIterations) + " Newton iterations";
  }
  return rep;
}

StepReport Integrator::step(SimulationState& state) {
  const auto t0 = std::chrono::steady_clock::now();
  const SimulationState saved = state;
  StepReport rep;
  double h = settings_.timeStep;
  int retries = 0;
  for (;; ++retries) {
    // Sub-steps of h until the full time step is covered.
    SimulationState s = saved;
    double done = 0;
    StepReport sub;
    int iterations = 0;
    bool ok = true;
    while (done < settings_.timeStep * (1 - 1e-9)) {
      const double hh = std::min(h, settings_.timeStep - done);
      sub = tryStep(s, hh);
      iterations += sub.newtonIterations;
      if (!sub.ok) {
        ok = false;
        break;
      }
      done += hh;
    }
    rep = sub;
    rep.newtonIterations = iterations;
    rep.timeStepUsed = h;
    if (ok) {
      state = s;
      rep.ok = true;
      rep.status = retries ? "converged with time step " + std::to_string(h) + " s after " + std::to_string(retries) + " retries"
                           : "converged";
      break;
    }
    if (retries >= settings_.maxRetries) {
      state = saved;  // rolled back
      rep.ok = false;
      rep.status += "; the step was rolled back";
      break;
    }
    h *= 0.5;
  }
  rep.retries = retries;
  rep.energy = totalEnergy(state);
  rep.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

StepReport Integrator::solveStatic(SimulationState& state, const Eigen::VectorXd& extra) {
  const auto t0 = std::chrono::steady_clock::now();
  StepReport rep;
  const SimulationState saved = state;
  Eigen::VectorXd fext = gravityForce_;
  if (extra.size() == fext.size()) fext += extra;
  auto potential = [&](const Eigen::VectorXd& x) { return elasticEnergy(model_, x) - fext.dot(x - model_.restVector()); };
  const double scale = std::max(fext.norm(), 1e-2 * model_.lumpedMass.sum());
  Eigen::VectorXd x = state.x;
  for (int it = 0; it < std::max(settings_.maxNewtonIterations, 30); ++it) {
    Eigen::VectorXd r = elasticForces(model_, x) + fext;  // out-of-balance force
    project(r);
    rep.residual = r.norm() / scale;
    if (!std::isfinite(rep.residual)) break;
    if (rep.residual <= settings_.tolerance) {
      rep.ok = true;
      break;
    }
    Eigen::SparseMatrix<double> K = elasticStiffness(model_, x);
    projectMatrix(K);
    Eigen::VectorXd dx;
    double shift = 0;
    bool solved = solveLinear(K, r, dx);
    // An indefinite tangent (large deformation): shift towards gradient descent until it factorises.
    while (!solved && shift < 1e12) {
      shift = shift == 0 ? 1e-6 * K.diagonal().cwiseAbs().maxCoeff() : shift * 10;
      Eigen::SparseMatrix<double> Ks = K;
      for (Eigen::Index i = 0; i < Ks.rows(); ++i) Ks.coeffRef(i, i) += shift;
      solved = solveLinear(Ks, r, dx);
    }
    if (!solved) {
      rep.status = "failed: the stiffness matrix could not be factorised";
      break;
    }
    project(dx);
    const double e0 = potential(x);
    double t = 1.0;
    Eigen::VectorXd xn = x + dx;
    if (settings_.lineSearch)
      while ((!std::isfinite(potential(xn)) || potential(xn) > e0 + 1e-4 * t * (-r.dot(dx))) && t > 1e-4) {
        t *= 0.5;
        xn = x + t * dx;
      }
    x = xn;
    ++rep.newtonIterations;
  }
  if (rep.ok && x.allFinite()) {
    state.x = x;
    state.v.setZero();
    rep.status = "converged";
  } else {
    state = saved;
    rep.ok = false;
    if (rep.status.empty()) rep.status = "not converged (relative residual " + std::to_string(rep.residual) + "); the state was rolled back";
  }
  rep.energy = totalEnergy(state);
  rep.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace rehearse::simcore
