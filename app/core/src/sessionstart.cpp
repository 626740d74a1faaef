// From a case to a body ready to run (sessionstart.hpp): the GUI's Simulation panel and `rehearse gesture` start
// their sessions here.
#include "rehearse/app/sessionstart.hpp"

#include <rehearse/app/materials.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/support.hpp>

#include <algorithm>
#include <functional>
#include <string>

namespace rehearse::app {
namespace {
// The tissue's viscosity in the rehearsal: stiffness-proportional (Kelvin-Voigt) damping, beta = 0.02 s (simcore's
// generic default is 0.1 s). Liver is viscoelastic and relaxes under a held strain (Liu and Bilston 2000, Biorheology
// 37:191: stress relaxation and oscillatory shear of liver in its linear range); we take its instantaneous stiffness
// as a small multiple of its relaxed one (our reading, about 3). With 10 ms steps, beta = 0.02 s makes a jump of the
// tool within one step meet (1 + beta / h) = 3 times the tissue's elastic stiffness, and a loss tangent omega beta =
// 0.13 at 1 Hz. With 0.1 s the same jump met 11 times: a mouse drag of 2 mm jumps read 2.2-2.8 times the patient
// liver's force at rest (bench_start --pull), and the grasp slipped at the scene's 15 N after a few pixels
// (helper-52); at 0.02 s, 1.3-1.5 times. At a hand's 20 mm/s the viscous share is 2-3 % of the force.
constexpr double kTissueDampingBeta = 0.02;  ///< s
}  // namespace

simcore::BodySetup bodySetup(const SessionRequest& s) {
  simcore::BodySetup b;
  b.mesh = s.organ->organ->volume;
  b.mesh.convertToMetres();
  const auto& shape = s.organ->shapeNodes();
  b.rest.resize(shape.size());
  for (std::size_t i = 0; i < shape.size(); ++i) b.rest[i] = s.organ->pose.apply(shape[i]);
  b.fixedNodes = s.organ->attachments;
  const LabelMaterials m = labelMaterials(
      MaterialSettings{s.model, s.young, s.poisson, s.density, s.vesselYoung, s.vesselPoisson, s.tearStrain});
  b.material = m.fallback;
  b.byLabel = m.byLabel;
  b.settings.timeStep = s.timeStep;
  b.settings.method = s.method;
  b.settings.accuracyPosition = s.accuracy;  // the surgeon's accuracy in millimetres and newtons (issue 64)
  b.settings.accuracyForce = 0.005;
  b.model = s.bodyModel;
  b.settings.factorRefresh =
      simcore::FactorRefresh::Asynchronous;  // the surgeon never waits for a factorisation (issue 15)
  b.settings.gravity = s.gravity;
  b.settings.rayleighStiffness = kTissueDampingBeta;
  // The step's error estimate (issue 64) every 10th step: the status line shows it at that rate, and the window stays
  // responsive (estimated at every step, the review window froze up to 125 ms on the phantom while the session ran).
  b.settings.estimateErrorEvery = 10;
  b.tools.toolRadius = s.toolRadius;
  b.tools.graspRadius = s.graspRadius;
  b.tools.clip.length = s.clipLength;
  // ... nor for a cut: its body comes in as soon as it is built (the step it came in at is recorded, so the replay
  // is exact). A fixed latency (the command line's, for runs that must end with the same mesh every time) made the
  // stepping thread wait for a late build: on the liver preset about 50 ms per cut when steps outrun real time.
  b.tools.cutLatencySteps = -1;
  // (A tear's body still waits at its boundary: taken in when built, ToolSettings::tearWhenBuilt, the patient liver's
  // pull tore 16 times instead of 7.)
  return b;
}

std::optional<simcore::InverseRestResult> RestShapeCache::find(std::uint64_t key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (key_ == key && result_) return result_;
  return std::nullopt;
}

void RestShapeCache::keep(std::uint64_t key, const simcore::InverseRestResult& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  key_ = key;
  result_ = r;
}

std::string SessionStart::patchesSentence() const {
  if (lone == 0 || held <= picked) return {};
  const std::size_t added = held - picked;
  return (lone == 1 ? std::string("The lone attachment holds its ") + std::to_string(added) + " neighbours"
                    : "The " + std::to_string(lone) + " lone attachments hold their " + std::to_string(added) +
                          " neighbours") +
         " too (" + std::to_string(held) +
         " nodes held): a ligament attaches over an area, and a single pinned node is crushed by a pull.";
}

SessionStart prepareStart(simcore::BodySetup body, const StartOptions& options) {
  SessionStart out;
  out.picked = body.fixedNodes.size();
  if (options.attachmentPatches && !body.fixedNodes.empty()) {
    std::vector<int> given = body.fixedNodes;
    std::sort(given.begin(), given.end());
    given.erase(std::unique(given.begin(), given.end()), given.end());
    out.picked = given.size();
    const std::vector<int> held = simcore::attachmentPatches(body.mesh, given, &out.lone);
    body.fixedNodes = held;
  }
  out.held = body.fixedNodes.size();
  // The tissue around the organ carries it: the FEM's springs (the other models hang it from its held nodes).
  const double support = body.model == simcore::BodyModel::Fem ? options.supportModulus : 0.0;
  const bool heavy = body.settings.gravity.norm() > 0;
  out.supportNotInModel = options.supportModulus > 0 && !(support > 0) && heavy;
  if (heavy && body.fixedNodes.empty() && !(support > 0)) {
    out.outcome = SessionStart::Outcome::NothingHolds;  // a falling organ is not a rehearsal
    return out;
  }
  const std::vector<Eigen::Vector3d> shape = body.rest.empty() ? body.mesh.points : body.rest;
  if (heavy && options.inEquilibrium) {
    // The shape is the equilibrium: the rest shape that sags into it, solved first (a few static solves).
    simcore::InverseRestOptions o;
    o.supportModulus = support;
    o.progress = options.progress;
    // The same organ, shape, attachments, material and settings as the last start: its rest shape again.
    std::uint64_t key = 0;
    if (options.cache) {
      key = setupHash(body) ^ std::hash<double>{}(support) * 0x9e3779b97f4a7c15ULL;  // (the solve places the support)
    }
    std::optional<simcore::InverseRestResult> r = options.cache ? options.cache->find(key) : std::nullopt;
    out.reused = r.has_value();
    if (!r) r = simcore::solveRestShape(body, shape, o);
    if (r->outcome == simcore::InverseRestResult::Outcome::Cancelled) {
      out.outcome = SessionStart::Outcome::Cancelled;
      return out;
    }
    if (options.cache && !out.reused) options.cache->keep(key, *r);
    out.rest = r;
    if (!r->converged()) {  // no equilibrium at the shape: the organ would leave it at once
      out.outcome = SessionStart::Outcome::NoEquilibrium;
      return out;
    }
    simcore::useRestShape(body, shape, *r);
    out.start = SessionStart::Start::InEquilibrium;
  } else if (heavy) {
    if (support > 0) {
      // At rest on the shape: the support carries the weight there, so it sags, not falls.
      simcore::Mesh rest = body.mesh;
      rest.points = shape;
      const simcore::FemModel m = simcore::FemModel::build(rest, body.byLabel, body.material);
      body.supports =
          simcore::placeSupports(body.mesh.tets, shape, m.lumpedMass, body.fixedNodes, body.settings.gravity, support)
              .anchors;
    }
    out.start = SessionStart::Start::SagsFromShape;
  }
  out.body = std::move(body);
  return out;
}

}  // namespace rehearse::app
