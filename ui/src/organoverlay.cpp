#include "rehearse/ui/organoverlay.hpp"

#include "rehearse/ui/gloverlay.hpp"
#include "rehearse/ui/pages/meshpage.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/registration.hpp>
#include <rehearse/simcore/session/field.hpp>

#include <QPainter>

#include <opencv2/imgproc.hpp>

namespace rehearse::ui {

OrganOverlay::OrganOverlay(bool openGL) {
  if (!openGL) return;
  gl_ = std::make_unique<GLOverlay>();
  if (!gl_->valid()) gl_.reset();
}

OrganOverlay::~OrganOverlay() = default;

namespace {
// Large frames (4k) get the overlay at a reduced resolution (`scale`), drawn scaled: the GUI thread stays
// responsive.
imaging::Camera overlayCamera(const imaging::Camera& camera, double& scale) {
  scale = std::min(1.0, 1600.0 / camera.width);
  imaging::Camera cam = camera;
  if (scale < 1.0) {
    cam.width = static_cast<int>(std::lround(camera.width * scale));
    cam.height = static_cast<int>(std::lround(camera.height * scale));
    cam.K.row(0) *= scale;
    cam.K.row(1) *= scale;
    cam.K(0, 2) = scale * (camera.cx() + 0.5) - 0.5;
    cam.K(1, 2) = scale * (camera.cy() + 0.5) - 0.5;
  }
  return cam;
}

// The outline of an overlay's covered pixels, in frame pixels.
QList<QPolygonF> silhouetteOf(const QImage& organ, double scale) {
  QList<QPolygonF> out;
  const cv::Mat overlay(organ.height(), organ.width(), CV_8UC4, const_cast<uchar*>(organ.constBits()), static_cast<std::size_t>(organ.bytesPerLine()));
  cv::Mat1b mask;
  cv::extractChannel(overlay, mask, 3);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  for (const auto& ct : contours) {
    QPolygonF poly;
    for (const auto& p : ct) poly << QPointF((p.x + 0.5) / scale, (p.y + 0.5) / scale);
    out << poly;
  }
  return out;
}
}  // namespace

QImage OrganOverlay::organImage(const imaging::Camera& camera, const Pose& pose, const SurfaceView& surface, const QColor& colour) {
  QImage image;
  if (gl_ && gl_->render(camera, pose, surface, colour, image)) return image;
  const cv::Mat4b overlay = imaging::renderOverlay(camera, pose, surface, cv::Vec3b(colour.blue(), colour.green(), colour.red()));
  cv::Mat rgba;
  cv::cvtColor(overlay, rgba, cv::COLOR_BGRA2RGBA);
  return QImage(rgba.data, rgba.cols, rgba.rows, static_cast<int>(rgba.step), QImage::Format_RGBA8888).copy();
}

OverlayPicture OrganOverlay::render(const app::Case& c, const std::vector<int>& innerLabels) {
  OverlayPicture out;
  if (c.organ->surface.empty() || !c.hasPose || !c.camera.problem().empty()) return out;
  double s = 1;
  const imaging::Camera cam = overlayCamera(c.camera, s);
  out.organ = organImage(cam, c.pose, c.surfaceView(), palette::organFill());
  out.silhouette = silhouetteOf(out.organ, s);
  // Inner structures the user ticked, on the organ's current shape (fitted or rest).
  drawInner(out, cam, c.pose, c.surfaceView(), c.organ->innerSurface, c.organ->innerSurfaceLabels, innerLabels,
            c.organ->volume);
  // The distance the elastic fit measures: the silhouette contour's points to the organ's visible
  // silhouette (its bent edges), in pixels of the frame.
  if (const auto segments = imaging::silhouetteSegments(c.contour); !segments.empty()) {
    const SurfaceView sv = c.surfaceView();
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(sv.vertexCount));
    for (std::size_t i = 0; i < sv.vertexCount; ++i) x.segment<3>(3 * static_cast<Eigen::Index>(i)) = sv.vertex(i);
    try {
      const auto d = simcore::contourResidual(segments, simcore::visibleSilhouette(c.organ->surface, x, c.pose, c.camera.pinhole()));
      if (d.points > 0 && std::isfinite(d.mean)) {
        out.meanDistance = d.mean;
        out.rmsDistance = d.rms;
        out.maxDistance = d.hausdorff;
      }
    } catch (const std::exception&) {
      // behind the camera: no distance to show
    }
  }
  return out;
}

void OrganOverlay::drawInner(OverlayPicture& out, const imaging::Camera& camera, const Pose& pose, SurfaceView view,
                             const std::vector<std::array<int, 3>>& faces, const std::vector<int>& faceLabels,
                             const std::vector<int>& innerLabels, const simcore::Mesh& names) {
  // Each label in its own colour (one render per label, composed in label order), named in the legend's key.
  std::vector<std::array<int, 3>> storage;
  for (int label : innerLabels) {
    storage.clear();
    for (std::size_t i = 0; i < faces.size() && i < faceLabels.size(); ++i)
      if (faceLabels[i] == label) storage.push_back(faces[i]);
    if (storage.empty()) continue;
    view.triangles = storage.front().data();
    view.triangleCount = storage.size();
    const QImage layer = organImage(camera, pose, view, labelColour(label));
    const std::string name = names.labelName(label);
    out.innerKey.push_back({labelColour(label), name.empty() ? QString::fromUtf8(simcore::structureKindName(names.labelKind(label))) +
                                                                   QStringLiteral(" (label %1)").arg(label)
                                                             : QString::fromStdString(name)});
    if (out.inner.isNull()) {
      out.inner = layer;
    } else {
      QPainter p(&out.inner);
      p.drawImage(0, 0, layer);
    }
  }
}

OverlayPicture OrganOverlay::renderLive(const app::Case& c, const std::vector<Eigen::Vector3d>& cameraPositions, const simcore::CutSurface& surface,
                                        std::shared_ptr<const std::vector<std::array<int, 4>>> tets,
                                        std::shared_ptr<const std::vector<int>> labels,
                                        const std::vector<int>& innerLabels) {
  OverlayPicture out;
  if (cameraPositions.empty() || surface.triangles.empty() || !c.camera.problem().empty()) return out;
  double s = 1;
  const imaging::Camera cam = overlayCamera(c.camera, s);
  std::vector<double> vertices;
  vertices.reserve(3 * cameraPositions.size());
  for (const auto& x : cameraPositions) vertices.insert(vertices.end(), {x.x(), x.y(), x.z()});
  SurfaceView sv;
  sv.vertices = vertices.data();
  sv.vertexCount = cameraPositions.size();
  sv.triangles = surface.triangles.front().data();
  sv.triangleCount = surface.triangles.size();
  try {
    const QColor fill = palette::organFill();
    cv::Mat4b shaded = imaging::renderOverlay(cam, Pose{}, sv, cv::Vec3b(fill.blue(), fill.green(), fill.red()));
    if (surface.cutCount > 0) {
      const imaging::Rasterization r = imaging::rasterize(cam, Pose{}, sv);
      for (int y = 0; y < shaded.rows; ++y)
        for (int x = 0; x < shaded.cols; ++x) {
          const int t = r.triangle(y, x);
          if (t < 0 || !surface.cut[static_cast<std::size_t>(t)]) continue;
          cv::Vec4b& p = shaded(y, x);
          const double shade = (p[0] + p[1] + p[2]) / (3.0 * std::max(1, (fill.red() + fill.green() + fill.blue()) / 3));
          p = cv::Vec4b(cv::saturate_cast<uchar>(40 * shade), cv::saturate_cast<uchar>(30 * shade), cv::saturate_cast<uchar>(160 * shade), p[3]);
        }
    }
    cv::Mat rgba;
    cv::cvtColor(shaded, rgba, cv::COLOR_BGRA2RGBA);
    out.organ = QImage(rgba.data, rgba.cols, rgba.rows, static_cast<int>(rgba.step), QImage::Format_RGBA8888).copy();
    // The inner structures on the cut mesh: the faces of their elements that are not shared with an element of the same
    // label (a cut vessel's stump included), found again only when the elements change (burnt ones keep their label).
    if (!innerLabels.empty() && tets && labels && labels->size() == tets->size()) {
      if (innerTets_ != tets || innerTetLabels_ != labels) {
        simcore::Mesh m;
        m.points = cameraPositions;
        m.tets = *tets;
        m.tetLabels.resize(labels->size());
        for (std::size_t e = 0; e < labels->size(); ++e) m.tetLabels[e] = simcore::unburntLabel((*labels)[e]);
        innerFaces_ = simcore::boundaryTriangles(m, true, &innerFaceLabels_);
        innerTets_ = std::move(tets);
        innerTetLabels_ = std::move(labels);
      }
      drawInner(out, cam, Pose{}, sv, innerFaces_, innerFaceLabels_, innerLabels, c.organ->volume);
    }
  } catch (const std::exception&) {
    return out;  // behind the camera or a bad camera: nothing to draw
  }
  out.silhouette = silhouetteOf(out.organ, s);
  return out;
}

}  // namespace rehearse::ui
