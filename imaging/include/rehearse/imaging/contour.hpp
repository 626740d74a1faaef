#pragma once
// The organ contour an assistant sketches over the frame: one or more (possibly open) segments in pixels
// of the undistorted frame. Files: our JSON {"image_size": [w, h], "segments": [{"points": [[u, v], ...],
// "closed": false}]} and the P2ILF challenge's {"numOfContours": N, "contour": [{"contourType": ...,
// "imagePoints": {"x": [...], "y": [...]}}]}.
#include <rehearse/imaging/camera.hpp>

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace rehearse::imaging {

struct ContourSegment {
  std::vector<Eigen::Vector2d> points;  ///< pixels
  bool closed = false;
  std::string type = "silhouette";      ///< silhouette, ridge or ligament (P2ILF's contour types)
  /// For a ridge or a ligament: the same curve on the organ, as node indices of its mesh in order along it
  /// (P2ILF's "modelPoints"), which makes it an anatomical curve constraint of the elastic fit.
  std::vector<int> modelVertices;
  /// Part of the organ's outline (a silhouette, or untyped), not a ridge or ligament inside it.
  bool isSilhouette() const { return type.empty() || type == "silhouette"; }
  bool operator==(const ContourSegment&) const = default;
};

struct Contour {
  int width = 0, height = 0;  ///< image size the points refer to
  std::vector<ContourSegment> segments;
  std::size_t pointCount() const;
  bool empty() const { return pointCount() == 0; }
  bool operator==(const Contour&) const = default;
};

/// Which file layout a contour came from. P2ILF's contours are drawn on the raw (distorted) images.
enum class ContourFormat { Rehearse, P2ILF };

/// Reads our JSON or the P2ILF JSON (detected from the keys; `format`, when given, says which). Throws
/// InputError with one sentence.
Contour loadContour(const std::string& path, ContourFormat* format = nullptr);
void saveContour(const Contour& c, const std::string& path);
/// The same from and to text (`name` names the source in messages); what the case file stores.
Contour parseContour(const std::string& text, const std::string& name, ContourFormat* format = nullptr);
std::string contourToJson(const Contour& c);
/// P2ILF's layout: {"numOfContours": N, "contour": [{"contourType": "Silhouette" | "Ridge" | "Ligament",
/// "imagePoints": {"x": [...], "y": [...]}, "modelPoints": {"vertices": [...]}}]}. The points are written as
/// given: pass the contour through distortContour first to put them on the raw image, as P2ILF does.
std::string contourToP2ILF(const Contour& c);
void saveContourP2ILF(const Contour& c, const std::string& path);

/// The outer borders of a binary mask, longest first, on the boundary between the mask and the background:
/// each border pixel's centre moved outwards half way to its outside neighbours (half a pixel across an
/// axis-aligned border, 0.35 px across a diagonal one). Borders of fewer than `minPoints` pixels are dropped.
/// The outline of a rendered organ, for tests and benchmarks of the fit.
std::vector<std::vector<Eigen::Vector2d>> maskOutlines(const cv::Mat1b& mask, std::size_t minPoints = 20);
/// The silhouette segments of a contour (not ridges or ligaments) as point lists, what the elastic fit
/// uses; a closed segment repeats its first point at the end.
std::vector<std::vector<Eigen::Vector2d>> silhouetteSegments(const Contour& c);

/// The ridge and ligament segments that carry their curve on the organ (modelVertices): the fit's anatomical
/// curve constraints.
std::vector<ContourSegment> anatomicalSegments(const Contour& c);

/// The contour of a raw (distorted) image moved to the undistorted frame of `camera` (as P2ILF's contours,
/// drawn on the raw images).
Contour undistortContour(const Contour& c, const Camera& camera);
/// The inverse: a contour of the undistorted frame moved onto the raw image through the camera's distortion
/// (what a P2ILF export holds). Unchanged when the camera has no distortion.
Contour distortContour(const Contour& c, const Camera& camera);
/// True when any distortion coefficient of the camera is non-zero.
bool hasDistortion(const Camera& camera);

/// The most points a contour holds (a file with more is refused; a sketch with more is not fitted): an outline drawn at
/// one point per pixel around a 4K frame holds about 12,000.
inline constexpr std::size_t kMaxContourPoints = 20000;

/// Empty when the contour can be used for fitting; otherwise one sentence (empty, a single point, too many points,
/// points outside the image, a segment that crosses itself).
std::string contourProblem(const Contour& c);

/// Points at uniform arc-length spacing (pixels) along the segment, ends kept (unchanged when that would
/// take a million points or more).
ContourSegment resampleSegment(const ContourSegment& s, double spacing);
/// Moving-average smoothing (Taubin lambda/mu so the contour does not shrink); open ends stay fixed.
ContourSegment smoothSegment(const ContourSegment& s, int iterations);
/// True when two non-adjacent edges of the segment cross.
bool segmentSelfIntersects(const ContourSegment& s);

/// Snaps a sketched polyline to image edges with OpenCV's intelligent scissors (live-wire) between
/// successive anchor points, each anchor first moved to the strongest edge within 12 px, each stretch
/// solved in a window 24 px around its two anchors (cost independent of the frame's size). `image` is the
/// frame (BGR). Returns the snapped polyline.
std::vector<Eigen::Vector2d> snapToEdges(const cv::Mat3b& image, const std::vector<Eigen::Vector2d>& anchors);

}  // namespace rehearse::imaging
