// The registration suite's shared parts: the BodyParts3D liver sagged by CalculiX (built once), the check of a fit's
// bound's far ends, and the phases of secondFrameFixesDepth (the second camera, the two frames' fits, the motion
// estimated from the features, the command line).
#pragma once
#include "registration_cases.hpp"

#include <memory>
#include <utility>

// The BodyParts3D liver sagged by CalculiX (see realLiverSagIsEstimatedWithThePose), built once.
struct SaggedLiver {
  std::shared_ptr<const app::Organ> organ;
  FemModel model;
  std::vector<int> attachments;
  imaging::Camera cam;
  Pose truth, start;
  Eigen::Vector3d gCamera;
  std::vector<Eigen::Vector2d> outline;
  std::vector<Eigen::Vector3d> markerTruth;  // camera frame
  std::vector<double> deformedVertices;      // CalculiX's sagged surface (model frame), for other views
  std::vector<std::array<int, 3>> deformedTriangles;
  SurfaceEmbedding embedded;
  double sag = 0;
  std::size_t fineTets = 0;
  // The mean distance of the markers (visible surface) from CalculiX's, m.
  double error(const RegistrationResult& r) const {
    const auto at = mapEmbedded(embedded, r.x);
    double e = 0;
    for (std::size_t i = 0; i < markerTruth.size(); ++i) e += (r.pose.apply(at[i]) - markerTruth[i]).norm();
    return e / static_cast<double>(markerTruth.size());
  }
  RegistrationResult fit(const std::vector<Eigen::Vector2d>& contour, const RegistrationOptions& o) const {
    SimulationSettings s;
    s.gravity.setZero();
    return registerToContour(model, attachments, s, organ->surface, {contour}, start, cam.pinhole(), o);
  }
  // CalculiX's sagged surface as a view for the renderer.
  SurfaceView deformedView() const {
    return {deformedVertices.data(), deformedVertices.size() / 3, deformedTriangles.front().data(),
            deformedTriangles.size()};
  }
};

// The bound's far ends (RegistrationUncertainty::ends), checked against their definition from scratch: two, on either
// side of the result, each moving the surface facing the camera (its front-facing triangles' nodes, seen from the
// camera at the result's pose) by the bound on average. Returns the two ends' mean moves (mm).
std::pair<double, double> checkEnds(const RegistrationResult& r,
                                    const std::vector<std::array<int, 3>>& surface);

// The fixture, built once into cache, or null with why ("absent: ..." when the data set is not there).
const SaggedLiver* loadSaggedLiver(std::unique_ptr<SaggedLiver>& cache, QString& why);

// secondFrameFixesDepth's phases (each asserts; the caller returns when one failed):
// the second camera, 15 mm across the first one's view and turned to the organ, and its outline of the sagged liver;
void makeSecondFrame(const SaggedLiver* L, RegistrationFrame& second);
// the fits on the outlines of both frames and with 200 features tracked between them (added to o), against one frame's;
void checkTwoFrames(const SaggedLiver* L, RegistrationOptions& o, const RegistrationResult& one);
// the fit through the motion estimated from those features, set aside or kept with its share in the bound;
void checkEstimatedMotion(const SaggedLiver* L, const RegistrationOptions& o, const RegistrationFrame& second,
                          const RegistrationResult& one);
// rehearse register with the second frame's outline and motion, and its refusals.
void checkSecondFrameCommandLine(const SaggedLiver* L, const RegistrationFrame& second);
