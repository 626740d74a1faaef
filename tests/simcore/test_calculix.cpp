// Against CalculiX (ccx, an independent FEM code) on the same C3D4 mesh: a cantilever under its own
// weight, linear (small load) and geometrically nonlinear. Like is compared with like:
//   ccx *ELASTIC + NLGEOM is Saint Venant-Kirchhoff      <-> our stvk (and our corotational, which differs
//                                                            from it only at finite strain: 2 % allowed);
//   ccx *HYPERELASTIC, NEO HOOKE: C10 (I1bar - 3) + (J-1)^2/D1  <-> our neohookean-split (the same law), and
//   our stable neohookean (mu/2 (I1 - 3) + lambda'/2 (J - alpha)^2, Smith et al. 2018), which shares the
//   small-strain law but not the volumetric term: its difference is reported and held to 2 %/5 %.
// Fails when ccx is not installed (scripts/install-deps.sh installs calculix-ccx).
#include "box_mesh.hpp"
#include "calculix.hpp"
#include "test_support.hpp"

#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <algorithm>
#include <numeric>

#include <QProcess>

#include <filesystem>
#include <sstream>
#include <QStandardPaths>

using namespace rehearse::simcore;

namespace {
// The cantilever's runs: one material, fixed nodes (default: the face x = 0), gravity g along `gdir`.
Eigen::VectorXd runCalculix(const Mesh& mesh, double E, double nu, double rho, double g, bool nlgeom, const std::string& name,
                            std::vector<int> fixed = {}, Eigen::Vector3d gdir = Eigen::Vector3d(0, 0, -1), bool neoHooke = false) {
  if (fixed.empty()) fixed = nodesAtX(mesh, 0);
  return runCalculixStatic(mesh, {}, {E, nu, rho, neoHooke}, g * gdir, nlgeom, fixed, name);
}

struct Result {
  double tipOurs, tipCcx, fieldError;
};

Result compare(MaterialModel model, double E, bool nlgeom, const std::string& name, bool neoHooke = false) {
  const double L = 0.1, b = 0.01, h = 0.01, nu = 0.3, rho = 1000, g = 9.81;
  Mesh mesh = boxMesh(L, b, h, 20, 2, 2);
  const Eigen::VectorXd ccx = runCalculix(mesh, E, nu, rho, g, nlgeom, name, {}, Eigen::Vector3d(0, 0, -1), neoHooke);
  if (ccx.size() == 0) return {0, 0, -1};
  FemModel m = FemModel::build(mesh, {}, {model, E, nu, rho});
  const std::vector<int> fixed = nodesAtX(mesh, 0);
  SimulationSettings s;
  s.gravity = Eigen::Vector3d(0, 0, -g);
  s.tolerance = 1e-8;
  Integrator in(m, fixed, s);
  auto st = in.initialState();
  auto rep = in.solveStatic(st);
  if (!rep.ok) return {0, 0, -2};
  const Eigen::VectorXd u = st.x - m.restVector();
  double tipO = 0, tipC = 0;
  int n = 0;
  for (std::size_t i = 0; i < mesh.points.size(); ++i)
    if (std::abs(mesh.points[i].x() - L) < 1e-12) {
      tipO += u[3 * i + 2];
      tipC += ccx[3 * i + 2];
      ++n;
    }
  return {tipO / n, tipC / n, (u - ccx).norm() / ccx.norm()};
}
}  // namespace

class TestCalculix : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    // The set-up installs CalculiX: a missing one fails the run instead of shrinking it.
    if (QStandardPaths::findExecutable("ccx").isEmpty()) QFAIL("CalculiX (ccx) is not installed; scripts/install-deps.sh installs calculix-ccx");
  }

  // Same mesh, same element, same load: linear elasticity must agree to solver precision.
  void linearCantilever() {
    const auto r = compare(MaterialModel::Linear, 1e7, false, "linear");
    QVERIFY2(r.fieldError >= 0, r.fieldError == -1 ? "ccx failed" : "our static solve failed");
    qInfo("linear: tip %.6f mm (ours) vs %.6f mm (CalculiX), relative L2 field difference %.2e", -r.tipOurs * 1e3, -r.tipCcx * 1e3,
          r.fieldError);
    QVERIFY(std::abs(r.tipOurs - r.tipCcx) / std::abs(r.tipCcx) < 1e-4);
    QVERIFY(r.fieldError < 1e-4);
  }

  // Large deflection (about half the length): CalculiX NLGEOM (St Venant-Kirchhoff) against our StVK.
  void nonlinearCantileverStVK() {
    const auto r = compare(MaterialModel::StVK, 1.2e5, true, "nlgeom");
    QVERIFY2(r.fieldError >= 0, r.fieldError == -1 ? "ccx failed" : "our static solve failed");
    qInfo("StVK NLGEOM: tip %.4f mm (ours) vs %.4f mm (CalculiX), relative L2 field difference %.2e", -r.tipOurs * 1e3, -r.tipCcx * 1e3,
          r.fieldError);
    QVERIFY(std::abs(r.tipCcx) > 0.01);  // really large: more than 10 mm on a 100 mm beam
    // The issue asks for 2 % on the tip and 5 % on the field; with the same mesh and element the two codes
    // agree to solver precision, so hold them to that.
    QVERIFY(std::abs(r.tipOurs - r.tipCcx) / std::abs(r.tipCcx) < 1e-4);
    QVERIFY(r.fieldError < 1e-4);
  }

  // The co-rotational model against the same NLGEOM run: large rotation, small strain, so within 2 %.
  void nonlinearCantileverCorotational() {
    const auto r = compare(MaterialModel::Corotational, 1.2e5, true, "corot");
    QVERIFY2(r.fieldError >= 0, r.fieldError == -1 ? "ccx failed" : "our static solve failed");
    const double tipError = std::abs(r.tipOurs - r.tipCcx) / std::abs(r.tipCcx);
    qInfo("corotational vs CalculiX NLGEOM (StVK): tip %.4f mm vs %.4f mm (%.2f %%), relative L2 field difference %.2e", -r.tipOurs * 1e3,
          -r.tipCcx * 1e3, 100 * tipError, r.fieldError);
    QVERIFY(std::abs(r.tipCcx) > 0.01);
    QVERIFY(tipError < 0.02);
    QVERIFY(r.fieldError < 0.05);
  }

  // Neo-Hookean: CalculiX's *HYPERELASTIC, NEO HOOKE against the same law (neohookean-split), and our
  // stable Neo-Hookean against it (different volumetric term: reported, within 2 % / 5 %).
  void nonlinearCantileverNeoHookean() {
    const auto same = compare(MaterialModel::NeoHookeanSplit, 1.2e5, true, "neohooke", true);
    QVERIFY2(same.fieldError >= 0, same.fieldError == -1 ? "ccx failed" : "our static solve failed");
    const auto stable = compare(MaterialModel::NeoHookean, 1.2e5, true, "neohooke-stable", true);
    QVERIFY2(stable.fieldError >= 0, stable.fieldError == -1 ? "ccx failed" : "our static solve failed");
    const double tipSame = std::abs(same.tipOurs - same.tipCcx) / std::abs(same.tipCcx);
    const double tipStable = std::abs(stable.tipOurs - stable.tipCcx) / std::abs(stable.tipCcx);
    qInfo("NEO HOOKE (CalculiX) tip %.4f mm; neohookean-split %.4f mm (%.2e, L2 %.2e); stable neohookean %.4f mm (%.2f %%, L2 %.2e)",
          -same.tipCcx * 1e3, -same.tipOurs * 1e3, tipSame, same.fieldError, -stable.tipOurs * 1e3, 100 * tipStable, stable.fieldError);
    QVERIFY(std::abs(same.tipCcx) > 0.01);
    QVERIFY(tipSame < 1e-3);
    QVERIFY(same.fieldError < 1e-3);
    QVERIFY(tipStable < 0.02);
    QVERIFY(stable.fieldError < 0.05);
  }

  // SOFA's liver2.msh (read in dm: a 21 cm liver) hanging from its top nodes under gravity, soft StVK.
  void hangingLiver2() {
    REQUIRE_SHARED("sofa/liver2.msh");
    Mesh mesh = loadMesh(sharedData("sofa/liver2.msh"), {"dm"});
    mesh.triangles.clear();
    mesh.triangleLabels.clear();
    // Attachments: the highest 3 % of the nodes (along +y).
    std::vector<int> order(mesh.points.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return mesh.points[a].y() > mesh.points[b].y(); });
    std::vector<int> fixed(order.begin(), order.begin() + mesh.points.size() * 3 / 100);
    const double E = 27e3, nu = 0.4, rho = 1000, g = 9.81;
    const Eigen::VectorXd ccxElastic = runCalculix(mesh, E, nu, rho, g, true, "liver2", fixed, Eigen::Vector3d(0, -1, 0));
    const Eigen::VectorXd ccxNeo = runCalculix(mesh, E, nu, rho, g, true, "liver2-neo", fixed, Eigen::Vector3d(0, -1, 0), true);
    // The co-rotational law is not St Venant-Kirchhoff at finite strain (12 % apart at 27 kPa, where the
    // strain near the attachments is large): like with like is the same sag geometry at small strain, 30x stiffer.
    const Eigen::VectorXd ccxStiff = runCalculix(mesh, 30 * E, nu, rho, g, true, "liver2-stiff", fixed, Eigen::Vector3d(0, -1, 0));
    QVERIFY2(ccxElastic.size() > 0 && ccxNeo.size() > 0 && ccxStiff.size() > 0, "ccx failed");
    for (MaterialModel model : {MaterialModel::StVK, MaterialModel::Corotational, MaterialModel::NeoHookeanSplit, MaterialModel::NeoHookean}) {
      const bool neo = model == MaterialModel::NeoHookeanSplit || model == MaterialModel::NeoHookean;
      const bool corot = model == MaterialModel::Corotational;
      const Eigen::VectorXd& ccx = neo ? ccxNeo : corot ? ccxStiff : ccxElastic;
      FemModel m = FemModel::build(mesh, {}, {model, corot ? 30 * E : E, nu, rho});
      SimulationSettings s;
      s.gravity = Eigen::Vector3d(0, -g, 0);
      s.tolerance = 1e-8;
      Integrator in(m, fixed, s);
      auto st = in.initialState();
      auto rep = in.solveStatic(st);
      QVERIFY2(rep.ok, rep.status.c_str());
      const Eigen::VectorXd u = st.x - m.restVector();
      Eigen::Index worst = 0;
      ccx.cwiseAbs().maxCoeff(&worst);
      const double field = (u - ccx).norm() / ccx.norm(), peak = std::abs(u[worst] - ccx[worst]) / std::abs(ccx[worst]);
      qInfo("liver2 hanging (%zu tets, %zu fixed), %s vs CalculiX %s%s: largest displacement %.3f mm vs %.3f mm (%.2f %%); relative L2 %.2e; "
            "%d Newton iterations",
            m.tets.size(), fixed.size(), toString(model).c_str(), neo ? "NEO HOOKE" : "ELASTIC NLGEOM", corot ? " (E = 810 kPa)" : "",
            std::abs(u[worst]) * 1e3,
            std::abs(ccx[worst]) * 1e3, 100 * peak, field, rep.newtonIterations);
      QVERIFY(std::abs(ccx[worst]) > 1e-3);
      // Our stable Neo-Hookean is another law than ccx's NEO HOOKE (volumetric term): 2.6 % apart at this
      // strain, reported and bounded by 5 %; the same law (neohookean-split) agrees to 1e-7.
      QVERIFY(peak < (model == MaterialModel::NeoHookean ? 0.05 : 0.02));
      QVERIFY(field < 0.05);
    }
  }
};

QTEST_GUILESS_MAIN(TestCalculix)
#include "test_calculix.moc"
