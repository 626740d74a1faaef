#include <rehearse/imaging/contour.hpp>
#include <rehearse/text_input.hpp>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/imgproc/segmentation.hpp>
#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

using nlohmann::json;

namespace rehearse::imaging {

std::size_t Contour::pointCount() const {
  std::size_t n = 0;
  for (const auto& s : segments) n += s.points.size();
  return n;
}

namespace {
double num(const json& j) { return j.is_string() ? std::stod(j.get<std::string>()) : j.get<double>(); }
}  // namespace

Contour loadContour(const std::string& path, ContourFormat* format) {
  std::string text, why;
  if (!readTextInput(path, text, why)) throw InputError("The contour file " + why + ".");
  return parseContour(text, std::filesystem::path(path).filename().string(), format);
}

namespace {
std::vector<int> vertexList(const json& j) {
  std::vector<int> out;
  for (const auto& v : j) {
    const double d = num(v);
    if (!(d >= 0) || d > 1e9 || d != std::floor(d)) throw InputError("a model vertex index is not a non-negative whole number.");
    out.push_back(static_cast<int>(d));
  }
  return out;
}
}  // namespace

Contour parseContour(const std::string& text, const std::string& name, ContourFormat* format) {
  if (const std::string why = jsonTextProblem(text, name); !why.empty()) throw InputError(why + ".");
  Contour c;
  try {
    const json j = json::parse(text);
    if (format) *format = j.contains("segments") ? ContourFormat::Rehearse : ContourFormat::P2ILF;
    if (j.contains("segments")) {
      if (j.contains("image_size")) {
        c.width = j["image_size"].at(0).get<int>();
        c.height = j["image_size"].at(1).get<int>();
      }
      for (const auto& s : j["segments"]) {
        ContourSegment seg;
        for (const auto& p : s.at("points")) seg.points.emplace_back(num(p.at(0)), num(p.at(1)));
        seg.closed = s.value("closed", false);
        seg.type = s.value("type", std::string("silhouette"));
        if (s.contains("model_vertices")) seg.modelVertices = vertexList(s["model_vertices"]);
        c.segments.push_back(std::move(seg));
      }
    } else if (j.contains("contour")) {  // P2ILF
      for (const auto& s : j["contour"]) {
        ContourSegment seg;
        std::string t = s.value("contourType", std::string("Silhouette"));
        for (auto& ch : t) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
        seg.type = t;
        const auto& xs = s.at("imagePoints").at("x");
        const auto& ys = s.at("imagePoints").at("y");
        if (xs.size() != ys.size()) throw InputError(name + ": a P2ILF contour has different numbers of x and y values.");
        for (std::size_t i = 0; i < xs.size(); ++i) seg.points.emplace_back(num(xs[i]), num(ys[i]));
        if (s.contains("modelPoints") && s["modelPoints"].contains("vertices")) seg.modelVertices = vertexList(s["modelPoints"]["vertices"]);
        c.segments.push_back(std::move(seg));
      }
    } else {
      throw InputError(name + " is not a contour file: it needs \"segments\" (Rehearse) or \"contour\" (P2ILF).");
    }
  } catch (const InputError& e) {
    const std::string what = e.what();
    if (what.rfind(name, 0) == 0) throw;
    throw InputError(name + ": " + what);
  } catch (const std::exception&) {
    throw InputError(name + " is not a valid contour file; see \"File formats\" in the README.");
  }
  for (const auto& s : c.segments)
    for (const auto& p : s.points)
      if (!p.allFinite()) throw InputError(name + " has a point that is not a finite number.");
  if (c.pointCount() > kMaxContourPoints)
    throw InputError(name + " holds " + std::to_string(c.pointCount()) + " points; an outline needs at most " +
                     std::to_string(kMaxContourPoints) + " (resample it to a few pixels' spacing).");
  return c;
}

std::string contourToJson(const Contour& c) {
  json j;
  j["image_size"] = {c.width, c.height};
  j["segments"] = json::array();
  for (const auto& s : c.segments) {
    json pts = json::array();
    for (const auto& p : s.points) pts.push_back({p.x(), p.y()});
    json seg = {{"points", pts}, {"closed", s.closed}, {"type", s.type}};
    if (!s.modelVertices.empty()) seg["model_vertices"] = s.modelVertices;
    j["segments"].push_back(std::move(seg));
  }
  return j.dump(1) + "\n";
}

void saveContour(const Contour& c, const std::string& path) { writeFileAtomically(path, contourToJson(c)); }

std::string contourToP2ILF(const Contour& c) {
  json j;
  j["numOfContours"] = c.segments.size();
  j["contour"] = json::array();
  for (const auto& s : c.segments) {
    json xs = json::array(), ys = json::array();
    for (const auto& p : s.points) {
      xs.push_back(p.x());
      ys.push_back(p.y());
    }
    std::string type = s.type.empty() ? std::string("silhouette") : s.type;
    type[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(type[0])));
    json seg = {{"contourType", type}, {"imagePoints", {{"x", xs}, {"y", ys}}}};
    if (!s.modelVertices.empty()) seg["modelPoints"] = {{"vertices", s.modelVertices}};
    j["contour"].push_back(std::move(seg));
  }
  return j.dump(1) + "\n";
}

void saveContourP2ILF(const Contour& c, const std::string& path) { writeFileAtomically(path, contourToP2ILF(c)); }

bool segmentSelfIntersects(const ContourSegment& s) {
  const auto& p = s.points;
  const std::size_t n = p.size();
  const std::size_t edges = s.closed ? n : (n ? n - 1 : 0);
  if (edges < 3) return false;
  auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
  auto crossing = [&](std::size_t i, std::size_t j) {
    if (i > j) std::swap(i, j);
    if (j < i + 2) return false;                      // the same edge or neighbours
    if (s.closed && i == 0 && j == n - 1) return false;  // neighbours through the closing edge
    const Eigen::Vector2d a = p[i], b = p[(i + 1) % n], c = p[j], d = p[(j + 1) % n];
    const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a), d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
    return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
  };
  // Edges bucketed in a uniform grid of about one edge per cell: only edges sharing a cell are tested (a drawn outline
  // of 20,000 points took seconds pair by pair; 400,000 never ended).
  Eigen::AlignedBox2d box;
  for (const auto& q : p) box.extend(q);
  const double extent = std::max(box.sizes().maxCoeff(), 1e-9);
  const int side = std::clamp(static_cast<int>(std::sqrt(static_cast<double>(edges))), 1, 1024);
  const double cell = extent / side * (1 + 1e-9);
  std::vector<std::vector<std::size_t>> grid(static_cast<std::size_t>(side) * static_cast<std::size_t>(side));
  auto cellOf = [&](double v, double lo) { return std::clamp(static_cast<int>((v - lo) / cell), 0, side - 1); };
  for (std::size_t i = 0; i < edges; ++i) {
    const Eigen::Vector2d a = p[i], b = p[(i + 1) % n];
    const int x0 = cellOf(std::min(a.x(), b.x()), box.min().x()), x1 = cellOf(std::max(a.x(), b.x()), box.min().x());
    const int y0 = cellOf(std::min(a.y(), b.y()), box.min().y()), y1 = cellOf(std::max(a.y(), b.y()), box.min().y());
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        auto& bucket = grid[static_cast<std::size_t>(y) * static_cast<std::size_t>(side) + static_cast<std::size_t>(x)];
        for (std::size_t j : bucket)
          if (crossing(i, j)) return true;
        bucket.push_back(i);
      }
  }
  return false;
}

std::string contourProblem(const Contour& c) {
  if (c.empty()) return "The contour is empty; sketch the organ's outline over the frame first.";
  if (c.pointCount() > kMaxContourPoints)
    return "The contour holds " + std::to_string(c.pointCount()) + " points; an outline needs at most " +
           std::to_string(kMaxContourPoints) + " (Resample it).";
  if (c.pointCount() < 2) return "The contour has a single point; sketch at least a short stretch of the outline.";
  for (std::size_t i = 0; i < c.segments.size(); ++i) {
    const auto& s = c.segments[i];
    if (c.width > 0 && c.height > 0)
      for (const auto& p : s.points)
        if (p.x() < -0.5 || p.y() < -0.5 || p.x() > c.width - 0.5 || p.y() > c.height - 0.5)
          return "Segment " + std::to_string(i + 1) + " has points outside the image; redraw it inside the frame.";
    if (segmentSelfIntersects(s))
      return "Segment " + std::to_string(i + 1) + " crosses itself; an organ outline cannot, so erase the loop and redraw it.";
  }
  return {};
}

ContourSegment resampleSegment(const ContourSegment& s, double spacing) {
  ContourSegment out = s;
  if (s.points.size() < 2 || !(spacing > 0)) return out;
  std::vector<Eigen::Vector2d> pts = s.points;
  if (s.closed) pts.push_back(s.points.front());
  std::vector<double> arc(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) arc[i] = arc[i - 1] + (pts[i] - pts[i - 1]).norm();
  const double total = arc.back();
  if (total <= 0) return out;
  if (!(total / spacing < 1e6)) return out;  // absurd coordinates (or spacing): left as they are
  const int n = std::max(1, static_cast<int>(std::round(total / spacing)));
  out.points.clear();
  std::size_t k = 0;
  for (int i = 0; i <= n; ++i) {
    if (s.closed && i == n) break;
    const double target = total * i / n;
    while (k + 1 < arc.size() - 1 && arc[k + 1] < target) ++k;
    const double len = arc[k + 1] - arc[k];
    const double t = len > 0 ? (target - arc[k]) / len : 0;
    out.points.push_back(pts[k] + t * (pts[k + 1] - pts[k]));
  }
  return out;
}

ContourSegment smoothSegment(const ContourSegment& s, int iterations) {
  ContourSegment out = s;
  const std::size_t n = s.points.size();
  if (n < 3) return out;
  auto pass = [&](double factor) {
    std::vector<Eigen::Vector2d> next = out.points;
    for (std::size_t i = 0; i < n; ++i) {
      if (!s.closed && (i == 0 || i + 1 == n)) continue;
      const auto& a = out.points[(i + n - 1) % n];
      const auto& b = out.points[(i + 1) % n];
      next[i] = out.points[i] + factor * (0.5 * (a + b) - out.points[i]);
    }
    out.points = std::move(next);
  };
  for (int it = 0; it < iterations; ++it) {
    pass(0.5);    // shrink
    pass(-0.53);  // inflate back (Taubin)
  }
  return out;
}

std::vector<Eigen::Vector2d> snapToEdges(const cv::Mat3b& image, const std::vector<Eigen::Vector2d>& anchors) {
  if (anchors.size() < 2 || image.empty()) return anchors;
  // Each stretch between two anchors is solved in a window around them (the anchors' box and a margin),
  // not on the whole frame: the live-wire's shortest-path map costs in proportion to the pixels it covers,
  // which on a 4k frame made one stroke take minutes, and the path has no business far from the stroke.
  constexpr int kSearch = 12;  // anchors first move to the strongest edge this close (the hand is never on it)
  constexpr int kMargin = 24;
  auto clampPt = [&](const Eigen::Vector2d& p) {
    return cv::Point(std::clamp(static_cast<int>(std::lround(p.x())), 0, image.cols - 1),
                     std::clamp(static_cast<int>(std::lround(p.y())), 0, image.rows - 1));
  };
  auto strongestNear = [&](const cv::Point& c) {
    const cv::Rect box = cv::Rect(c.x - kSearch - 1, c.y - kSearch - 1, 2 * kSearch + 3, 2 * kSearch + 3) & cv::Rect(0, 0, image.cols, image.rows);
    cv::Mat gray, gx, gy, magnitude;
    cv::cvtColor(image(box), gray, cv::COLOR_BGR2GRAY);
    cv::Sobel(gray, gx, CV_32F, 1, 0);
    cv::Sobel(gray, gy, CV_32F, 0, 1);
    cv::magnitude(gx, gy, magnitude);
    cv::Point best = c;
    float bestValue = magnitude.at<float>(c - box.tl());
    for (int dy = -kSearch; dy <= kSearch; ++dy)
      for (int dx = -kSearch; dx <= kSearch; ++dx) {
        const cv::Point q(c.x + dx, c.y + dy);
        if (!box.contains(q) || q.x == box.x || q.y == box.y || q.x == box.br().x - 1 || q.y == box.br().y - 1 ||
            dx * dx + dy * dy > kSearch * kSearch)
          continue;  // the window's border has one-sided gradients
        const float m = magnitude.at<float>(q - box.tl());
        if (m > bestValue * 1.05f) {
          bestValue = m;
          best = q;
        }
      }
    return best;
  };
  std::vector<cv::Point> snappedAnchors;
  for (const auto& a : anchors) snappedAnchors.push_back(strongestNear(clampPt(a)));
  std::vector<Eigen::Vector2d> out;
  for (std::size_t i = 0; i + 1 < snappedAnchors.size(); ++i) {
    const cv::Point from = snappedAnchors[i], to = snappedAnchors[i + 1];
    const cv::Rect window = (cv::Rect(std::min(from.x, to.x) - kMargin, std::min(from.y, to.y) - kMargin,
                                      std::abs(from.x - to.x) + 2 * kMargin + 1, std::abs(from.y - to.y) + 2 * kMargin + 1)) &
                            cv::Rect(0, 0, image.cols, image.rows);
    cv::segmentation::IntelligentScissorsMB scissors;
    scissors.setEdgeFeatureCannyParameters(32, 100);
    scissors.setGradientMagnitudeMaxLimit(200);
    scissors.applyImage(image(window).clone());
    scissors.buildMap(from - window.tl());
    std::vector<cv::Point> path;
    scissors.getContour(to - window.tl(), path);
    if (path.empty()) {
      if (out.empty()) out.emplace_back(from.x, from.y);
      out.emplace_back(to.x, to.y);
      continue;
    }
    for (auto& q : path) q += window.tl();
    // Order the path from this anchor to the next whatever order the library returns.
    if (cv::norm(path.front() - from) > cv::norm(path.back() - from)) std::reverse(path.begin(), path.end());
    for (std::size_t k = (out.empty() ? 0 : 1); k < path.size(); ++k) out.emplace_back(path[k].x, path[k].y);
  }
  return out;
}

}  // namespace rehearse::imaging

namespace rehearse::imaging {

std::vector<std::vector<Eigen::Vector2d>> maskOutlines(const cv::Mat1b& mask, std::size_t minPoints) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::sort(contours.begin(), contours.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  std::vector<std::vector<Eigen::Vector2d>> out;
  for (const auto& ct : contours) {
    if (ct.size() < minPoints) continue;
    // findContours gives the border pixels' centres; the boundary lies half way to the outside pixels.
    const std::size_t n = ct.size();
    double area = 0;
    for (std::size_t i = 0; i < n; ++i) area += double(ct[i].x) * ct[(i + 1) % n].y - double(ct[(i + 1) % n].x) * ct[i].y;
    std::vector<Eigen::Vector2d> seg;
    for (std::size_t i = 0; i < n; ++i) {
      const cv::Point d = ct[(i + 2) % n] - ct[(i + n - 2) % n];
      Eigen::Vector2d normal(d.y, -d.x);
      if (area < 0) normal = -normal;
      if (normal.norm() > 0) normal.normalize();
      seg.push_back(Eigen::Vector2d(ct[i].x, ct[i].y) + 0.5 * normal.cwiseAbs().maxCoeff() * normal);
    }
    out.push_back(std::move(seg));
  }
  return out;
}

std::vector<std::vector<Eigen::Vector2d>> silhouetteSegments(const Contour& c) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  for (const auto& seg : c.segments)
    if (seg.isSilhouette()) {
      out.push_back(seg.points);
      if (seg.closed && !seg.points.empty()) out.back().push_back(seg.points.front());
    }
  return out;
}

std::vector<ContourSegment> anatomicalSegments(const Contour& c) {
  std::vector<ContourSegment> out;
  for (const auto& seg : c.segments)
    if (!seg.isSilhouette() && !seg.modelVertices.empty()) out.push_back(seg);
  return out;
}

bool hasDistortion(const Camera& camera) {
  bool distorted = false;
  for (double d : camera.distortion) distorted |= d != 0;
  return distorted;
}

Contour undistortContour(const Contour& c, const Camera& camera) {
  if (!hasDistortion(camera)) return c;
  cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) K.at<double>(r, k) = camera.K(r, k);
  for (int k = 0; k < 5; ++k) D.at<double>(0, k) = camera.distortion[k];
  Contour out = c;
  for (auto& seg : out.segments) {
    if (seg.points.empty()) continue;
    std::vector<cv::Point2d> in, und;
    for (const auto& p : seg.points) in.emplace_back(p.x(), p.y());
    cv::undistortPoints(in, und, K, D, cv::noArray(), K);  // back to pixels of the undistorted frame
    for (std::size_t i = 0; i < und.size(); ++i) seg.points[i] = Eigen::Vector2d(und[i].x, und[i].y);
  }
  return out;
}

Contour distortContour(const Contour& c, const Camera& camera) {
  if (!hasDistortion(camera)) return c;
  cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) K.at<double>(r, k) = camera.K(r, k);
  for (int k = 0; k < 5; ++k) D.at<double>(0, k) = camera.distortion[k];
  const Eigen::Matrix3d Kinv = camera.K.inverse();
  Contour out = c;
  for (auto& seg : out.segments) {
    if (seg.points.empty()) continue;
    std::vector<cv::Point3d> rays;  // the pixel's ray at unit depth
    for (const auto& p : seg.points) {
      const Eigen::Vector3d r = Kinv * Eigen::Vector3d(p.x(), p.y(), 1.0);
      rays.emplace_back(r.x() / r.z(), r.y() / r.z(), 1.0);
    }
    std::vector<cv::Point2d> raw;
    cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D, raw);
    for (std::size_t i = 0; i < raw.size(); ++i) seg.points[i] = Eigen::Vector2d(raw[i].x, raw[i].y);
  }
  return out;
}

}  // namespace rehearse::imaging
