// The hybrid model's core (hybrid.hpp): the rest's responses at the interface by Eigen's sparse LDLT, its stiffness
// condensed onto the interface, the region's system solved with the held nodes eliminated.
#include <rehearse/simcore/hybrid.hpp>
#include <rehearse/simcore/precomputed.hpp>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <mutex>
#include <set>

namespace rehearse::simcore {

struct HybridElasticity::Parts {
  std::size_t n = 0;
  std::vector<char> fixed;
  std::vector<int> pIndex, rIndex;  ///< node -> its block in the rest's / region's free unknowns (-1: none)
  Eigen::VectorXd restSag;          ///< u_I^0: the rest's others' sag with the interface held still
  Eigen::MatrixXd responses;        ///< R_IG: their displacement per unit displacement of each interface unknown
  std::vector<int> interfaceDofs;   ///< the interface's free unknowns, in the rest's numbering
  std::vector<int> restDofs;        ///< the rest's other free unknowns (I), in the rest's numbering
  std::vector<int> pNode;           ///< the rest's free node index -> node
  Eigen::MatrixXd condensed;        ///< S = K_GG + K_GI R_IG
  Eigen::VectorXd restPull;         ///< K_GI u_I^0
  std::vector<std::array<int, 4>> restTets;  ///< the rest's elements (whether a rebuild may keep its responses)
  std::vector<double> restKey;               ///< their moduli, the rest's nodes' rest positions and masses
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  Eigen::SparseMatrix<double> A;    ///< the region's K_R with S added on the interface (its free unknowns)
  Eigen::VectorXd b;                ///< f_R - K_GI u_I^0 on the interface
  // The region's system with the last held nodes eliminated, factorised (solve() reuses it for the same held nodes).
  std::mutex cacheMutex;
  bool cacheValid = false;
  std::vector<int> cachedHeld, freeIndex, heldDofs;
  Eigen::SparseMatrix<double> Afh;
  Eigen::VectorXd bf;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
};

HybridElasticity::HybridElasticity() : p_(std::make_unique<Parts>()) {}
HybridElasticity::HybridElasticity(HybridElasticity&&) noexcept = default;
HybridElasticity& HybridElasticity::operator=(HybridElasticity&&) noexcept = default;
HybridElasticity::~HybridElasticity() = default;

std::size_t HybridElasticity::memoryBytes() const {
  return sizeof(double) * static_cast<std::size_t>(p_->responses.size() + p_->condensed.size() + p_->restSag.size());
}

const std::vector<char>& HybridElasticity::fixedNodes() const { return p_->fixed; }

bool HybridElasticity::inRegion(int node) const {
  return node >= 0 && static_cast<std::size_t>(node) < p_->n && p_->rIndex[static_cast<std::size_t>(node)] >= 0;
}

namespace {
// The stiffness at rest of the elements `keep` marks (the others' moduli zeroed), 3n x 3n.
Eigen::SparseMatrix<double> partStiffness(const FemModel& model, const std::vector<char>& keep) {
  FemModel part = model;
  for (std::size_t e = 0; e < part.tets.size(); ++e)
    if (!keep[e]) part.lame[e] = Lame{};
  Eigen::SparseMatrix<double> K;
  assembleStiffness(part, part.restVector(), K);
  return K;
}
// Nodes joined into pieces (union-find with path halving).
struct Pieces {
  std::vector<int> root;
  explicit Pieces(std::size_t n) : root(n) {
    for (std::size_t v = 0; v < n; ++v) root[v] = static_cast<int>(v);
  }
  int find(int v) {
    while (root[static_cast<std::size_t>(v)] != v)
      v = root[static_cast<std::size_t>(v)] = root[static_cast<std::size_t>(root[static_cast<std::size_t>(v)])];
    return v;
  }
  void join(const std::array<int, 4>& t) {
    for (int k = 1; k < 4; ++k) root[static_cast<std::size_t>(find(t[static_cast<std::size_t>(k)]))] = find(t[0]);
  }
};

// Rows and columns of K for the nodes with index[node] >= 0 (3 each).
Eigen::SparseMatrix<double> restrict(const Eigen::SparseMatrix<double>& K, const std::vector<int>& index, int size) {
  std::vector<Eigen::Triplet<double>> t;
  for (int c = 0; c < K.outerSize(); ++c) {
    const int cn = index[static_cast<std::size_t>(c / 3)];
    if (cn < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
      const int rn = index[static_cast<std::size_t>(it.row() / 3)];
      if (rn < 0) continue;
      t.emplace_back(3 * rn + static_cast<int>(it.row() % 3), 3 * cn + c % 3, it.value());
    }
  }
  Eigen::SparseMatrix<double> out(3 * size, 3 * size);
  out.setFromTriplets(t.begin(), t.end());
  return out;
}

constexpr const char* kRestNotHeld =
    "The part of the organ outside the FEM region is not held by an attachment: a free part has no static "
    "response (attach the organ there too).";

// A piece of the organ no attachment holds (a cut took it off) has no static equilibrium: it would fall. A static
// model cannot let it, so it is held where it is (its nodes fixed at rest), counted and said (freePieces). Returns how
// many pieces were held.
std::size_t holdFreePieces(const FemModel& model, std::vector<char>& fixed) {
  const std::size_t n = model.nodeCount();
  std::size_t freePieces = 0;
  Pieces pieces(n);
  const auto find = [&](int v) { return pieces.find(v); };
  for (const auto& t : model.tets) pieces.join(t);
  std::vector<char> anchored(n, 0), used(n, 0);
  for (const auto& t : model.tets)
    for (int v : t) used[static_cast<std::size_t>(v)] = 1;
  for (std::size_t v = 0; v < n; ++v)
    if (fixed[v]) anchored[static_cast<std::size_t>(find(static_cast<int>(v)))] = 1;
  std::vector<char> counted(n, 0);
  for (std::size_t v = 0; v < n; ++v) {
    const auto r = static_cast<std::size_t>(find(static_cast<int>(v)));
    if (!used[v] || anchored[r]) continue;
    fixed[v] = 1;
    if (!counted[r]) counted[r] = 1, ++freePieces;
  }
  return freePieces;
}

// The rest's pieces (its elements joined through shared nodes) that no attachment holds would float: each has no
// static response of its own (its stiffness is singular), so it joins the FEM region.
void absorbFloatingRest(const FemModel& model, const std::vector<char>& fixed, std::vector<char>& inRegion) {
  const std::size_t n = model.nodeCount(), m = model.tets.size();
  Pieces pieces(n);
  const auto find = [&](int v) { return pieces.find(v); };
  for (std::size_t e = 0; e < m; ++e)
    if (!inRegion[e]) pieces.join(model.tets[e]);
  std::vector<char> anchored(n, 0);
  for (std::size_t e = 0; e < m; ++e)
    if (!inRegion[e])
      for (int v : model.tets[e])
        if (fixed[static_cast<std::size_t>(v)]) anchored[static_cast<std::size_t>(find(v))] = 1;
  for (std::size_t e = 0; e < m; ++e)
    if (!inRegion[e] && !anchored[static_cast<std::size_t>(find(model.tets[e][0]))]) inRegion[e] = 1;
}

// The rest's responses at the interface and its stiffness condensed onto it (see HybridElasticity::Parts).
struct RestCondensation {
  Eigen::VectorXd restSag;
  Eigen::MatrixXd responses;
  std::vector<int> interfaceDofs, restDofs;
  Eigen::MatrixXd condensed;
  Eigen::VectorXd restPull;
};

// The rest's free unknowns split into the interface's (G) and the others (I), K_II factorised, and from it u_I^0,
// R_IG, S and K_GI u_I^0 (see build()). False, with `why`, when the rest's stiffness is singular.
bool condenseRest(const FemModel& model, const std::vector<char>& restElements, const std::vector<int>& pIndex, int np,
                  const std::vector<int>& interfaceNodes, const std::vector<int>& restNodes,
                  const Eigen::Vector3d& gravity, RestCondensation& p, std::string& why) {
  const Eigen::SparseMatrix<double> KP = restrict(partStiffness(model, restElements), pIndex, np);
  std::vector<int> split(static_cast<std::size_t>(3 * np), -1);  // P unknown -> G index (>= 0) or -(I index) - 2
  int ng = 0, ni = 0;
  for (int v : interfaceNodes)
    if (pIndex[static_cast<std::size_t>(v)] >= 0)
      for (int a = 0; a < 3; ++a) {
        const int dof = 3 * pIndex[static_cast<std::size_t>(v)] + a;
        split[static_cast<std::size_t>(dof)] = ng++;
        p.interfaceDofs.push_back(dof);
      }
  p.restDofs.clear();
  for (int dof = 0; dof < 3 * np; ++dof)
    if (split[static_cast<std::size_t>(dof)] < 0)
      split[static_cast<std::size_t>(dof)] = -(ni++) - 2, p.restDofs.push_back(dof);
  std::vector<Eigen::Triplet<double>> tII, tIG;
  Eigen::MatrixXd KGG = Eigen::MatrixXd::Zero(ng, ng);
  for (int c = 0; c < KP.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(KP, c); it; ++it) {
      const int r = split[static_cast<std::size_t>(it.row())], k = split[static_cast<std::size_t>(c)];
      if (r < -1 && k < -1)
        tII.emplace_back(-r - 2, -k - 2, it.value());
      else if (r < -1 && k >= 0)
        tIG.emplace_back(-r - 2, k, it.value());
      else if (r >= 0 && k >= 0)
        KGG(r, k) += it.value();
    }
  Eigen::SparseMatrix<double> KII(ni, ni), KIG(ni, ng);
  KII.setFromTriplets(tII.begin(), tII.end());
  KIG.setFromTriplets(tIG.begin(), tIG.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> restSolver(KII);
  if (restSolver.info() != Eigen::Success) {
    why = "The stiffness of the part outside the FEM region could not be factorised (a piece of it is free).";
    return false;
  }
  Eigen::VectorXd fI = Eigen::VectorXd::Zero(ni);
  for (int v : restNodes)
    if (pIndex[static_cast<std::size_t>(v)] >= 0)
      for (int a = 0; a < 3; ++a)
        fI[-split[static_cast<std::size_t>(3 * pIndex[static_cast<std::size_t>(v)] + a)] - 2] =
            model.lumpedMass[v] * gravity[a];
  p.restSag = restSolver.solve(fI);
  p.responses = -restSolver.solve(Eigen::MatrixXd(KIG));
  if (!p.responses.allFinite() || !p.restSag.allFinite()) {
    why = "The responses of the part outside the FEM region are not finite (its stiffness is singular).";
    return false;
  }
  p.condensed = KGG + Eigen::MatrixXd(KIG.transpose()) * p.responses;
  p.condensed = 0.5 * (p.condensed + p.condensed.transpose());
  p.restPull = KIG.transpose() * p.restSag;  // K_GI u_I^0: the rest's weight felt at the interface
  return true;
}

// The region's system: its own stiffness over its free nodes plus S on the interface (A); its load: every node it
// touches, and S u_G^g from the rest (b).
void assembleRegion(const FemModel& model, const std::vector<char>& inRegion, const std::vector<int>& rIndex, int nr,
                    const std::vector<int>& interfaceNodes, const std::vector<int>& regionNodes,
                    const Eigen::MatrixXd& condensed, const Eigen::VectorXd& restPull, int ng,
                    const Eigen::Vector3d& gravity, Eigen::SparseMatrix<double>& A, Eigen::VectorXd& b) {
  Eigen::SparseMatrix<double> KR = restrict(partStiffness(model, inRegion), rIndex, nr);
  std::vector<int> gInR;  // the interface's free unknowns in the region's numbering (same order as interfaceDofs)
  for (int v : interfaceNodes)
    if (rIndex[static_cast<std::size_t>(v)] >= 0)
      for (int a = 0; a < 3; ++a) gInR.push_back(3 * rIndex[static_cast<std::size_t>(v)] + a);
  std::vector<Eigen::Triplet<double>> t;
  for (int c = 0; c < KR.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(KR, c); it; ++it)
      t.emplace_back(static_cast<int>(it.row()), c, it.value());
  for (int i = 0; i < ng; ++i)
    for (int j = 0; j < ng; ++j)
      t.emplace_back(gInR[static_cast<std::size_t>(i)], gInR[static_cast<std::size_t>(j)], condensed(i, j));
  A.resize(3 * nr, 3 * nr);
  A.setFromTriplets(t.begin(), t.end());
  b = Eigen::VectorXd::Zero(3 * nr);
  for (int v : regionNodes)
    if (rIndex[static_cast<std::size_t>(v)] >= 0)
      b.segment<3>(3 * rIndex[static_cast<std::size_t>(v)]) = model.lumpedMass[v] * gravity;
  for (int k = 0; k < ng; ++k) b[gInR[static_cast<std::size_t>(k)]] -= restPull[k];
}
}  // namespace

std::optional<HybridElasticity> HybridElasticity::build(const FemModel& model, const std::vector<char>& fixedIn,
                                                        const std::vector<char>& region, const Eigen::Vector3d& gravity,
                                                        std::string& why, const HybridElasticity* previous) {
  const std::size_t n = model.nodeCount(), m = model.tets.size();
  if (fixedIn.size() != n || region.size() != m) {
    why = "The hybrid model's fixed nodes or region do not match the mesh.";
    return std::nullopt;
  }
  if (std::find(fixedIn.begin(), fixedIn.end(), 1) == fixedIn.end()) {
    why = "The organ is not held by an attachment: a free body has no static response (attach it first).";
    return std::nullopt;
  }
  std::vector<char> fixed = fixedIn;
  const std::size_t freePieces = holdFreePieces(model, fixed);
  const auto inRegionCount = static_cast<std::size_t>(std::count(region.begin(), region.end(), 1));
  if (inRegionCount == 0 || inRegionCount == m) {
    why = inRegionCount == 0 ? "The hybrid model's FEM region is empty: choose the precomputed model instead."
                             : "The hybrid model's FEM region is the whole organ: choose the FEM instead.";
    return std::nullopt;
  }
  std::vector<char> inRegion(region.begin(), region.end());
  absorbFloatingRest(model, fixed, inRegion);
  if (std::count(inRegion.begin(), inRegion.end(), 1) == static_cast<long>(m)) {
    why = kRestNotHeld;
    return std::nullopt;
  }
  std::vector<char> inR(n, 0), inP(n, 0);
  std::vector<char> restElements(m, 0);
  for (std::size_t e = 0; e < m; ++e) {
    restElements[e] = !inRegion[e];
    for (int v : model.tets[e]) (inRegion[e] ? inR : inP)[static_cast<std::size_t>(v)] = 1;
  }
  bool held = false;
  for (std::size_t v = 0; v < n; ++v) held = held || (inP[v] && fixed[v]);
  if (!held) {
    why = kRestNotHeld;
    return std::nullopt;
  }
  HybridElasticity h;
  h.freePieces_ = freePieces;
  Parts& p = *h.p_;
  p.n = n;
  p.fixed = fixed;
  p.pIndex.assign(n, -1);
  p.rIndex.assign(n, -1);
  int np = 0, nr = 0;
  for (std::size_t v = 0; v < n; ++v) {
    if (inR[v]) h.regionNodes_.push_back(static_cast<int>(v));
    if (inR[v] && inP[v]) h.interface_.push_back(static_cast<int>(v));
    if (inP[v] && !inR[v]) h.restNodes_.push_back(static_cast<int>(v));
    if (fixed[v]) continue;
    if (inP[v]) p.pIndex[v] = np++, p.pNode.push_back(static_cast<int>(v));
    if (inR[v]) p.rIndex[v] = nr++;
  }
  // The rest, its free unknowns split into the interface's (G) and the others (I): K_II factorised; the others' sag
  // with the interface held still, u_I^0 = K_II^-1 f_I (the rest's own nodes' weight); their responses to a unit
  // displacement of each interface unknown, R_IG = -K_II^-1 K_IG (Cotin's tensors, to displacements); the rest's
  // stiffness condensed onto the interface, S = K_GG + K_GI R_IG. (Inverting the interface's compliance instead lost
  // five digits on a 50 mm region: the compliance of a soft body's interface is far worse conditioned.)
  std::vector<std::array<int, 4>> restTets;
  std::vector<double> restKey;  // what else the rest's stiffness and load depend on: moduli, rest positions, masses
  for (std::size_t e = 0; e < m; ++e)
    if (restElements[e]) {
      restTets.push_back(model.tets[e]);
      restKey.push_back(model.lame[e].mu), restKey.push_back(model.lame[e].lambda);
    }
  for (int v : p.pNode)
    for (int a = 0; a < 3; ++a) restKey.push_back(model.rest[static_cast<std::size_t>(v)][a]);
  for (int v : h.restNodes_) restKey.push_back(model.lumpedMass[v]);  // (the interface's weight is the region's)
  if (previous && previous->p_->restTets == restTets && previous->interface_ == h.interface_ &&
      previous->p_->pNode == p.pNode && previous->p_->gravity == gravity && previous->p_->restKey == restKey) {
    // The rest is as it was (a cut stayed in the region, which may have grown without reaching it): its responses hold.
    const Parts& q = *previous->p_;
    p.restSag = q.restSag, p.responses = q.responses, p.condensed = q.condensed, p.restPull = q.restPull;
    p.interfaceDofs = q.interfaceDofs, p.restDofs = q.restDofs;
    h.reused_ = true;
  } else {
    RestCondensation c;
    if (!condenseRest(model, restElements, p.pIndex, np, h.interface_, h.restNodes_, gravity, c, why))
      return std::nullopt;
    p.restSag = std::move(c.restSag), p.responses = std::move(c.responses);
    p.interfaceDofs = std::move(c.interfaceDofs), p.restDofs = std::move(c.restDofs);
    p.condensed = std::move(c.condensed), p.restPull = std::move(c.restPull);
  }
  const int ng = static_cast<int>(p.interfaceDofs.size());
  p.restTets = std::move(restTets);
  p.restKey = std::move(restKey);
  p.gravity = gravity;
  h.absorbed_ = static_cast<std::size_t>(std::count(inRegion.begin(), inRegion.end(), 1)) - inRegionCount;
  assembleRegion(model, inRegion, p.rIndex, nr, h.interface_, h.regionNodes_, p.condensed, p.restPull, ng, gravity,
                 p.A, p.b);
  return h;
}

bool HybridElasticity::solve(const std::vector<int>& held, const std::vector<Eigen::Vector3d>& displacement,
                             Eigen::VectorXd& u, std::vector<Eigen::Vector3d>* forces, std::string& why) const {
  Parts& p = *p_;  // (its factorisation cache changes; the mutex keeps solves one at a time)
  if (held.size() != displacement.size()) {
    why = "Each held node needs its displacement.";
    return false;
  }
  std::set<int> seen;
  for (int v : held) {
    if (!inRegion(v) || p.fixed[static_cast<std::size_t>(v)]) {
      why = "Node " + std::to_string(v) +
            " is outside the hybrid model's FEM region or fixed: an instrument can hold the "
            "region's free nodes only.";
      return false;
    }
    if (!seen.insert(v).second) {
      why = "Node " + std::to_string(v) + " is held twice.";
      return false;
    }
  }
  const int nr = static_cast<int>(p.b.size()) / 3;
  // The region's unknowns: held ones known, the others solved (A_ff u_f = b_f - A_fh u_h). A_ff's factorisation is
  // kept for the same held nodes (an instrument holds the same ones from step to step: a solve is then two
  // triangular solves).
  Eigen::VectorXd uR = Eigen::VectorXd::Zero(3 * nr);
  for (std::size_t k = 0; k < held.size(); ++k)
    uR.segment<3>(3 * p.rIndex[static_cast<std::size_t>(held[k])]) = displacement[k];
  std::lock_guard<std::mutex> lock(p.cacheMutex);
  if (!factorFor(held, why)) return false;
  Eigen::VectorXd uh(static_cast<Eigen::Index>(p.heldDofs.size()));
  for (std::size_t k = 0; k < p.heldDofs.size(); ++k) uh[static_cast<Eigen::Index>(k)] = uR[p.heldDofs[k]];
  const Eigen::VectorXd uf = p.solver.solve(p.bf - p.Afh * uh);
  const std::vector<int>& freeIndex = p.freeIndex;
  for (int i = 0; i < 3 * nr; ++i)
    if (freeIndex[static_cast<std::size_t>(i)] >= 0) uR[i] = uf[freeIndex[static_cast<std::size_t>(i)]];
  if (!uR.allFinite()) {
    why = "The hybrid model's displacement is not finite.";
    return false;
  }
  if (forces) {  // the instrument's force on the tissue: A u - b at the held nodes
    const Eigen::VectorXd residual = p.A * uR - p.b;
    forces->clear();
    for (int v : held) forces->push_back(residual.segment<3>(3 * p.rIndex[static_cast<std::size_t>(v)]));
  }
  expand(uR, u);
  return true;
}

bool HybridElasticity::factorFor(const std::vector<int>& held, std::string& why) const {
  Parts& p = *p_;  // (the caller holds cacheMutex)
  const int nr = static_cast<int>(p.b.size()) / 3;
  if (!p.cacheValid || p.cachedHeld != held) {
    p.cacheValid = false;
    std::vector<char> isHeld(static_cast<std::size_t>(3 * nr), 0);
    for (int v : held)
      for (int a = 0; a < 3; ++a) isHeld[static_cast<std::size_t>(3 * p.rIndex[static_cast<std::size_t>(v)] + a)] = 1;
    p.freeIndex.assign(static_cast<std::size_t>(3 * nr), -1);
    p.heldDofs.clear();
    int nf = 0;
    for (int i = 0; i < 3 * nr; ++i) {
      if (!isHeld[static_cast<std::size_t>(i)])
        p.freeIndex[static_cast<std::size_t>(i)] = nf++;
      else
        p.heldDofs.push_back(i);
    }
    std::vector<Eigen::Triplet<double>> tf, th;
    std::vector<int> heldColumn(static_cast<std::size_t>(3 * nr), -1);
    for (std::size_t k = 0; k < p.heldDofs.size(); ++k)
      heldColumn[static_cast<std::size_t>(p.heldDofs[k])] = static_cast<int>(k);
    for (int c = 0; c < p.A.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(p.A, c); it; ++it) {
        const int fr = p.freeIndex[static_cast<std::size_t>(it.row())], fc = p.freeIndex[static_cast<std::size_t>(c)];
        if (fr < 0) continue;
        if (fc >= 0)
          tf.emplace_back(fr, fc, it.value());
        else
          th.emplace_back(fr, heldColumn[static_cast<std::size_t>(c)], it.value());
      }
    Eigen::SparseMatrix<double> Aff(nf, nf);
    Aff.setFromTriplets(tf.begin(), tf.end());
    p.Afh.resize(nf, static_cast<Eigen::Index>(p.heldDofs.size()));
    p.Afh.setFromTriplets(th.begin(), th.end());
    p.bf.resize(nf);
    for (int i = 0; i < 3 * nr; ++i)
      if (p.freeIndex[static_cast<std::size_t>(i)] >= 0) p.bf[p.freeIndex[static_cast<std::size_t>(i)]] = p.b[i];
    p.solver.compute(Aff);
    if (p.solver.info() != Eigen::Success) {
      why = "The FEM region's system could not be factorised.";
      return false;
    }
    p.cachedHeld = held;
    p.cacheValid = true;
  }
  return true;
}

void HybridElasticity::expand(const Eigen::VectorXd& uR, Eigen::VectorXd& u) const {
  const Parts& p = *p_;
  // The whole organ: the region's nodes from its solve, the rest's by superposition of their responses to the
  // interface's displacement: u_I = u_I^0 + R_IG u_G.
  const int ng = static_cast<int>(p.interfaceDofs.size());
  Eigen::VectorXd uG(ng);
  {
    int k = 0;
    for (int v : interface_)
      if (p.rIndex[static_cast<std::size_t>(v)] >= 0)
        for (int a = 0; a < 3; ++a, ++k) uG[k] = uR[3 * p.rIndex[static_cast<std::size_t>(v)] + a];
  }
  const Eigen::VectorXd uI = p.restSag + p.responses * uG;
  u = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(3 * p.n));
  for (int v : regionNodes_)
    if (p.rIndex[static_cast<std::size_t>(v)] >= 0)
      u.segment<3>(3 * v) = uR.segment<3>(3 * p.rIndex[static_cast<std::size_t>(v)]);
  for (std::size_t k = 0; k < p.restDofs.size(); ++k) {
    const int dof = p.restDofs[k], node = p.pNode[static_cast<std::size_t>(dof / 3)];
    u[3 * node + dof % 3] = uI[static_cast<Eigen::Index>(k)];
  }
}

bool HybridElasticity::solveRows(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& base, bool withSag,
                                 Eigen::VectorXd& u, Eigen::VectorXd& lambda, Eigen::MatrixXd* Wout,
                                 std::string& why) const {
  Parts& p = *p_;
  const Eigen::Index m = static_cast<Eigen::Index>(rows.size());
  lambda.setZero(m);
  if (Wout) Wout->resize(m, m);
  if (base.size() != static_cast<Eigen::Index>(3 * p.n)) {
    why = "The hybrid model's base positions do not match its mesh.";
    return false;
  }
  auto node = [](const ScalarConstraint& r, int k) { return r.nodes[static_cast<std::size_t>(k)]; };
  auto weight = [](const ScalarConstraint& r, int k) { return r.weights[static_cast<std::size_t>(k)]; };
  // A row's force acts on its free nodes (a fixed node's share goes to the attachment); each must be the region's.
  for (const auto& r : rows)
    for (int k = 0; k < 4; ++k) {
      const int v = node(r, k);
      if (v < 0 || weight(r, k) == 0) continue;
      if (static_cast<std::size_t>(v) >= p.n) {
        why = "An instrument acts on node " + std::to_string(v) + ", which the organ does not have.";
        return false;
      }
      if (!p.fixed[static_cast<std::size_t>(v)] && !inRegion(v)) {
        why = "An instrument acts on node " + std::to_string(v) + ", outside the hybrid model's FEM region.";
        return false;
      }
    }
  std::lock_guard<std::mutex> lock(p.cacheMutex);
  if (!factorFor({}, why)) return false;  // no held nodes: the region's whole system (kept from step to step)
  const int nr = static_cast<int>(p.b.size()) / 3;
  // The sag (no instrument), then one solve per row: the region's response to the row's unit force.
  const Eigen::VectorXd sagR = p.solver.solve(p.b);
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(3 * nr, m);
  for (Eigen::Index c = 0; c < m; ++c) {
    const auto& cc = rows[static_cast<std::size_t>(c)];
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * nr);
    for (int k = 0; k < 4; ++k) {
      const int v = node(cc, k);
      if (v >= 0 && p.rIndex[static_cast<std::size_t>(v)] >= 0)
        f.segment<3>(3 * p.rIndex[static_cast<std::size_t>(v)]) += weight(cc, k) * cc.direction;
    }
    if (!f.isZero(0)) X.col(c) = p.solver.solve(f);
  }
  Eigen::VectorXd uR0 = withSag ? sagR : Eigen::VectorXd::Zero(3 * nr);
  Eigen::MatrixXd W(m, m);
  Eigen::VectorXd e(m);
  auto rowOf = [&](const ScalarConstraint& r, const Eigen::VectorXd& xR) {  // G_r on region displacements
    double g = 0;
    for (int k = 0; k < 4; ++k) {
      const int v = node(r, k);
      if (v >= 0 && p.rIndex[static_cast<std::size_t>(v)] >= 0)
        g += weight(r, k) * r.direction.dot(xR.segment<3>(3 * p.rIndex[static_cast<std::size_t>(v)]));
    }
    return g;
  };
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& cr = rows[static_cast<std::size_t>(r)];
    e(r) = cr.value - constraintValue(cr, base) - rowOf(cr, uR0);
    for (Eigen::Index c = 0; c < m; ++c) W(r, c) = rowOf(cr, X.col(c));
  }
  W = (0.5 * (W + W.transpose())).eval();
  if (Wout) *Wout = W;
  if (!settleRows(rows, W, e, lambda, why)) return false;
  const Eigen::VectorXd uR = uR0 + X * lambda;
  if (!uR.allFinite()) {
    why = "The hybrid model's displacement is not finite.";
    return false;
  }
  if (withSag) {
    expand(uR, u);
  } else {  // from the base itself: the rest's sag is not added either
    expand(uR + sagR, u);
    Eigen::VectorXd sag;
    expand(sagR, sag);
    u -= sag;
  }
  return true;
}

}  // namespace rehearse::simcore
