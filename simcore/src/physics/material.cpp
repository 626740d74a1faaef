#include <rehearse/simcore/material.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/SVD>

#include <cmath>

namespace rehearse::simcore {
namespace {

Eigen::Matrix3d cofactor(const Eigen::Matrix3d& F) {
  Eigen::Matrix3d C;
  C.col(0) = F.col(1).cross(F.col(2));
  C.col(1) = F.col(2).cross(F.col(0));
  C.col(2) = F.col(0).cross(F.col(1));
  return C;
}

Eigen::Matrix3d cofactorDifferential(const Eigen::Matrix3d& F, const Eigen::Matrix3d& dF) {
  Eigen::Matrix3d C;
  C.col(0) = dF.col(1).cross(F.col(2)) + F.col(1).cross(dF.col(2));
  C.col(1) = dF.col(2).cross(F.col(0)) + F.col(2).cross(dF.col(0));
  C.col(2) = dF.col(0).cross(F.col(1)) + F.col(0).cross(dF.col(1));
  return C;
}

Eigen::Matrix3d cross(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

// Parameters of the stable Neo-Hookean form without the log barrier: mu' = mu, lambda' = lambda + mu
// linearise to the same small-strain behaviour as the other models (P ~ mu (H + H^T) + lambda tr(H) I).
Lame stable(const Lame& p) { return {p.mu, p.lambda + p.mu}; }

// The corotational law's volume barrier (Lame::barrier): k b(J) for 0 < J < Jb, b(J) = -(J - Jb)^2 ln(J / Jb); its
// value, first and second derivatives in J (zero outside; an inverted element, J <= 0, is the inversion guard's and its
// own law's: the barrier is not defined there and adds nothing).
struct Barrier {
  double e = 0, d1 = 0, d2 = 0;
  bool active() const { return d1 != 0 || d2 != 0; }
};
Barrier volumeBarrier(const Lame& p, double J) {
  Barrier b;
  const double Jb = p.barrier;
  if (!(Jb > 0) || !(J > 0) || J >= Jb) return b;
  const double k = kVolumeBarrierStiffness * (p.lambda + p.mu), d = J - Jb, l = std::log(J / Jb);
  b.e = -k * d * d * l;
  b.d1 = -k * (2 * d * l + d * d / J);
  b.d2 = -k * (2 * l + 4 * d / J - d * d / (J * J));
  return b;
}

// The split Neo-Hookean of CalculiX and Abaqus (*HYPERELASTIC, NEO HOOKE):
//   W = C10 (J^-2/3 I1 - 3) + (J - 1)^2 / D1,  C10 = mu / 2,  D1 = 2 / K,  K = lambda + 2 mu / 3.
// Not defined for inverted elements: J is clamped to a small positive value there.
constexpr double kMinJ = 1e-6;
struct Split {
  double J, a, I1, C10, K;
  Eigen::Matrix3d FinvT;
};
Split split(const Lame& p, const Eigen::Matrix3d& F) {
  Split s;
  s.J = std::max(F.determinant(), kMinJ);
  s.a = std::pow(s.J, -2.0 / 3.0);
  s.I1 = F.squaredNorm();
  s.C10 = 0.5 * p.mu;
  s.K = p.lambda + 2.0 / 3.0 * p.mu;
  s.FinvT = cofactor(F) / s.J;  // F^-T = cof(F) / det F
  return s;
}

}  // namespace

MaterialModel materialModelFromString(const std::string& n) {
  if (n == "linear") return MaterialModel::Linear;
  if (n == "corotational") return MaterialModel::Corotational;
  if (n == "stvk") return MaterialModel::StVK;
  if (n == "neohookean") return MaterialModel::NeoHookean;
  if (n == "neohookean-split") return MaterialModel::NeoHookeanSplit;
  throw MeshError("Unknown material '" + n + "'; use linear, corotational, stvk, neohookean or neohookean-split.");
}

std::string toString(MaterialModel m) {
  switch (m) {
    case MaterialModel::Linear:
      return "linear";
    case MaterialModel::Corotational:
      return "corotational";
    case MaterialModel::StVK:
      return "stvk";
    case MaterialModel::NeoHookeanSplit:
      return "neohookean-split";
    default:
      return "neohookean";
  }
}

void polarDecomposition(const Eigen::Matrix3d& F, Eigen::Matrix3d& R, Eigen::Matrix3d& S) {
  // Well-conditioned, non-inverted F (nearly every element, nearly always): Higham's scaled Newton iteration
  // X <- (g X + X^-T / g) / 2 while X is far from orthogonal, then Newton-Schulz X <- X (I - E / 2), E = X^T X - I,
  // which needs no inverse and squares the orthogonality error (3/4 |E|^2) as Newton does: the same rotation to
  // round-off in half the time of Newton alone on the patient liver's strains (polar decompositions were a third of
  // a converged step there; issue 34). Inverted or nearly flat elements take the SVD below.
  const double det = F.determinant(), size = F.squaredNorm();
  if (det > 1e-3 * (size / 3) * std::sqrt(size / 3)) {
    Eigen::Matrix3d X = F;
    bool converged = false;
    for (int it = 0; it < 30 && !converged; ++it) {
      const Eigen::Vector3d a = X.col(0), b = X.col(1), c = X.col(2);
      const double e00 = a.squaredNorm() - 1, e11 = b.squaredNorm() - 1, e22 = c.squaredNorm() - 1;
      const double e01 = a.dot(b), e02 = a.dot(c), e12 = b.dot(c);
      const double e2 = e00 * e00 + e11 * e11 + e22 * e22 + 2 * (e01 * e01 + e02 * e02 + e12 * e12);
      if (e2 < 0.09) {  // |E| < 0.3: well inside Newton-Schulz's basin (|E|_2 < 1)
        X.col(0) = a - 0.5 * (a * e00 + b * e01 + c * e02);
        X.col(1) = b - 0.5 * (a * e01 + b * e11 + c * e12);
        X.col(2) = c - 0.5 * (a * e02 + b * e12 + c * e22);
        converged = e2 < 1e-16;  // |E| < 1e-8 before this step: under 1e-16 after it
      } else {
        // X^-T = cof(X) / det(X); g = (|X^-1| / |X|)^(1/2), Higham's Frobenius scaling.
        Eigen::Matrix3d C;
        C.col(0) = b.cross(c);
        C.col(1) = c.cross(a);
        C.col(2) = a.cross(b);
        const double d = a.dot(C.col(0));
        const double g = std::sqrt(std::sqrt(C.squaredNorm() / (d * d * X.squaredNorm())));
        X = (0.5 * g) * X + (0.5 / (g * d)) * C;
      }
    }
    if (converged && X.allFinite()) {
      R = X;
      S = R.transpose() * F;
      S = 0.5 * (S + S.transpose());
      return;
    }
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  // Rotation variant of the SVD: a reflection goes into the smallest singular value (inverted elements).
  if (U.determinant() < 0) U.col(2) *= -1;
  if (V.determinant() < 0) V.col(2) *= -1;
  R = U * V.transpose();
  S = R.transpose() * F;
  S = 0.5 * (S + S.transpose());
}

double energyDensity(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  switch (m) {
    case MaterialModel::Linear: {
      const Eigen::Matrix3d e = 0.5 * (F + F.transpose()) - I;
      return p.mu * e.squaredNorm() + 0.5 * p.lambda * e.trace() * e.trace();
    }
    case MaterialModel::Corotational: {
      Eigen::Matrix3d R, S;
      polarDecomposition(F, R, S);
      const double t = (S - I).trace();
      return p.mu * (F - R).squaredNorm() + 0.5 * p.lambda * t * t + volumeBarrier(p, F.determinant()).e;
    }
    case MaterialModel::StVK: {
      const Eigen::Matrix3d E = 0.5 * (F.transpose() * F - I);
      return p.mu * E.squaredNorm() + 0.5 * p.lambda * E.trace() * E.trace();
    }
    case MaterialModel::NeoHookeanSplit: {
      const Split q = split(p, F);
      return q.C10 * (q.a * q.I1 - 3) + 0.5 * q.K * (q.J - 1) * (q.J - 1);
    }
    default: {
      const Lame s = stable(p);
      const double alpha = 1 + s.mu / s.lambda, J = F.determinant();
      return 0.5 * s.mu * (F.squaredNorm() - 3) + 0.5 * s.lambda * (J - alpha) * (J - alpha);
    }
  }
}

Eigen::Matrix3d firstPiola(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, const TangentCache& c) {
  if (m != MaterialModel::Corotational) return firstPiola(m, p, F);
  Eigen::Matrix3d P = 2 * p.mu * (F - c.R) + p.lambda * (c.S.trace() - 3) * c.R;
  if (p.barrier > 0) {
    const Barrier b = volumeBarrier(p, F.determinant());
    if (b.active()) P += b.d1 * cofactor(F);
  }
  return P;
}

Eigen::Matrix3d firstPiola(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  switch (m) {
    case MaterialModel::Linear: {
      const Eigen::Matrix3d e = 0.5 * (F + F.transpose()) - I;
      return 2 * p.mu * e + p.lambda * e.trace() * I;
    }
    case MaterialModel::Corotational: {
      Eigen::Matrix3d R, S;
      polarDecomposition(F, R, S);
      Eigen::Matrix3d P = 2 * p.mu * (F - R) + p.lambda * (S.trace() - 3) * R;  // as with a prepared tangent, to the bit
      if (p.barrier > 0) {
        const Barrier b = volumeBarrier(p, F.determinant());
        if (b.active()) P += b.d1 * cofactor(F);
      }
      return P;
    }
    case MaterialModel::StVK: {
      const Eigen::Matrix3d E = 0.5 * (F.transpose() * F - I);
      return F * (2 * p.mu * E + p.lambda * E.trace() * I);
    }
    case MaterialModel::NeoHookeanSplit: {
      const Split q = split(p, F);
      return q.C10 * (2 * q.a * F - (2.0 / 3.0) * q.a * q.I1 * q.FinvT) + q.K * (q.J - 1) * q.J * q.FinvT;
    }
    default: {
      const Lame s = stable(p);
      const double alpha = 1 + s.mu / s.lambda, J = F.determinant();
      return s.mu * F + s.lambda * (J - alpha) * cofactor(F);
    }
  }
}

Eigen::Matrix3d firstPiolaDifferential(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F,
                                       const Eigen::Matrix3d& dF) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  switch (m) {
    case MaterialModel::Linear: {
      const Eigen::Matrix3d de = 0.5 * (dF + dF.transpose());
      return 2 * p.mu * de + p.lambda * de.trace() * I;
    }
    case MaterialModel::Corotational:
      return firstPiolaDifferential(m, p, F, prepareTangent(m, F), dF);
    case MaterialModel::StVK: {
      const Eigen::Matrix3d E = 0.5 * (F.transpose() * F - I);
      const Eigen::Matrix3d dE = 0.5 * (dF.transpose() * F + F.transpose() * dF);
      const Eigen::Matrix3d Sst = 2 * p.mu * E + p.lambda * E.trace() * I;
      const Eigen::Matrix3d dS = 2 * p.mu * dE + p.lambda * dE.trace() * I;
      return dF * Sst + F * dS;
    }
    case MaterialModel::NeoHookeanSplit: {
      const Split q = split(p, F);
      const double tr = q.FinvT.cwiseProduct(dF).sum();  // tr(F^-1 dF)
      const double dJ = q.J * tr, da = -2.0 / 3.0 * q.a * tr, dI1 = 2 * F.cwiseProduct(dF).sum();
      const Eigen::Matrix3d dFinvT = -q.FinvT * dF.transpose() * q.FinvT;
      const Eigen::Matrix3d dP1 = q.C10 * (2 * da * F + 2 * q.a * dF - (2.0 / 3.0) * (da * q.I1 + q.a * dI1) * q.FinvT -
                                           (2.0 / 3.0) * q.a * q.I1 * dFinvT);
      const Eigen::Matrix3d dP2 = q.K * ((2 * q.J - 1) * dJ * q.FinvT + (q.J * q.J - q.J) * dFinvT);
      return dP1 + dP2;
    }
    default: {
      const Lame s = stable(p);
      const double alpha = 1 + s.mu / s.lambda, J = F.determinant();
      const Eigen::Matrix3d C = cofactor(F);
      return s.mu * dF + s.lambda * (C.cwiseProduct(dF).sum()) * C +
             s.lambda * (J - alpha) * cofactorDifferential(F, dF);
    }
  }
}

TangentCache prepareTangent(MaterialModel m, const Eigen::Matrix3d& F) {
  TangentCache c;
  if (m != MaterialModel::Corotational) return c;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  polarDecomposition(F, c.R, c.S);
  Eigen::Matrix3d G = c.S.trace() * I - c.S;
  // Near-singular G (degenerate or inverted elements): regularise so the tangent stays finite.
  const double sn = c.S.norm();
  if (std::abs(G.determinant()) < 1e-12 * std::max(1.0, sn * sn * sn)) G += 1e-6 * std::max(1.0, c.S.norm()) * I;
  c.Ginv = G.inverse();
  return c;
}

Eigen::Matrix3d firstPiolaDifferential(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, const TangentCache& c,
                                       const Eigen::Matrix3d& dF) {
  if (m != MaterialModel::Corotational) return firstPiolaDifferential(m, p, F, dF);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  // dR = R [w]x with (tr(S) I - S) w = axial(R^T dF - dF^T R); B = R^T dF once (B - B^T is the skew part).
  const Eigen::Matrix3d B = c.R.transpose() * dF;
  const Eigen::Vector3d w = c.Ginv * Eigen::Vector3d(B(2, 1) - B(1, 2), B(0, 2) - B(2, 0), B(1, 0) - B(0, 1));
  const Eigen::Matrix3d dR = c.R * cross(w);
  Eigen::Matrix3d dP = 2 * p.mu * (dF - dR) + p.lambda * B.trace() * c.R + p.lambda * (c.S - I).trace() * dR;
  if (p.barrier > 0) {
    const Barrier b = volumeBarrier(p, F.determinant());
    if (b.active()) {
      const Eigen::Matrix3d C = cofactor(F);
      dP += b.d2 * C.cwiseProduct(dF).sum() * C + b.d1 * cofactorDifferential(F, dF);
    }
  }
  return dP;
}

}  // namespace rehearse::simcore
