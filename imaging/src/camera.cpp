#include <rehearse/imaging/camera.hpp>
#include <rehearse/text_input.hpp>
#include <rehearse/simcore/input_checks.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace rehearse::imaging {

namespace {
constexpr double kMaxPoseTranslationMetres = 10;
}

std::string Camera::problem() const {
  if (width <= 0 || height <= 0) return "The camera has no image size; give image_width and image_height.";
  if (width > 16384 || height > 16384) return "The camera's image size is implausibly large (over 16384 pixels).";
  if (!K.allFinite() || !(fx() > 0) || !(fy() > 0))
    return "The camera matrix is degenerate (focal lengths must be positive numbers); check the calibration file.";
  if (K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1)
    return "The camera matrix must have the form [fx s cx; 0 fy cy; 0 0 1]; check the calibration file.";
  for (double d : distortion)
    if (!std::isfinite(d) || std::abs(d) > 100) return "The distortion coefficients are not plausible numbers.";
  return {};
}

Camera Camera::defaultFor(int width, int height) {
  Camera c;
  c.width = width;
  c.height = height;
  c.K << 0.8 * width, 0, (width - 1) / 2.0, 0, 0.8 * width, (height - 1) / 2.0, 0, 0, 1;
  return c;
}

namespace {
std::string readText(const std::string& path, const char* what) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(std::string("The ") + what + " file " + path + " does not exist; check the path.");
  std::string text, why;
  if (!readTextInput(path, text, why, std::size_t{1} << 20)) throw InputError(std::string("The ") + what + " file " + why + ".");
  return text;
}

std::string ext(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  for (auto& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

double num(const nlohmann::json& j) {
  if (j.is_number()) return j.get<double>();
  if (j.is_string()) return std::stod(j.get<std::string>());  // P2ILF stores numbers as strings
  throw InputError("expected a number");
}

// An image size from a JSON number: whole and within int (a cast of 1e300 is undefined); 0 (refused later) otherwise.
int imageSize(double v) { return std::isfinite(v) && v >= 0 && v <= 1e6 ? static_cast<int>(v) : 0; }

Camera finish(Camera c, const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  if (auto p = c.problem(); !p.empty()) throw InputError(name + ": " + p);
  // Plausible for the image: a focal length of 1e-300 px or 1e300 px is damage, and overflowed the registration's
  // integer pixel casts ("-2147483648 px"). A 1 degree to 179.4 degree field of view lies well inside these bounds.
  const double w = c.width, h = c.height;
  if (c.fx() < 0.01 * w || c.fx() > 100 * w || c.fy() < 0.01 * w || c.fy() > 100 * w)
    throw InputError(name + ": the focal lengths (" + std::to_string(c.fx()).substr(0, 16) + ", " +
                     std::to_string(c.fy()).substr(0, 16) + " px) are implausible for a " + std::to_string(c.width) +
                     " px wide image (0.01 to 100 times its width); check the calibration file.");
  if (!(c.K(0, 2) >= -w && c.K(0, 2) <= 2 * w && c.K(1, 2) >= -h && c.K(1, 2) <= 2 * h) || !(std::abs(c.K(0, 1)) <= 100 * w))
    throw InputError(name + ": the principal point lies far outside the " + std::to_string(c.width) + " x " +
                     std::to_string(c.height) + " image (or the skew is absurd); check the calibration file.");
  return c;
}
}  // namespace

Camera loadCamera(const std::string& path, int width, int height) {
  const std::string e = ext(path);
  const std::string name = fs::path(path).filename().string();
  Camera c;
  c.width = width;
  c.height = height;
  if (e == ".yaml" || e == ".yml" || e == ".xml") {
    // Existence and size with our messages, then our own scan: cv::FileStorage crashed (SIGSEGV) on a file nested
    // 50,000 deep.
    const std::string text = readText(path, "camera");
    if (const std::string p = simcore::checks::calibrationMarkupProblem(text, e == ".xml"); !p.empty())
      throw InputError(name + " is not a camera calibration this program reads: " + p + "; check the file.");
    try {
      cv::FileStorage fsx(path, cv::FileStorage::READ);
      if (!fsx.isOpened()) throw InputError(name + " is not an OpenCV calibration file; check its format.");
      // OpenCV allocates a matrix of the rows and columns its node declares before it reads the data (found by
      // fuzzing: "cols: 2147483647" asked for 16 GiB): a calibration's matrices are small, so larger ones are refused
      // before they are read.
      auto readMatrix = [&](const char* key, cv::Mat& m) {
        const cv::FileNode node = fsx[key];
        if (node.empty()) return;
        // (Two ints multiply exactly in 64 bits.)
        const long long count = node.isMap() ? static_cast<long long>(static_cast<int>(node["rows"])) *
                                                   static_cast<long long>(static_cast<int>(node["cols"]))
                                             : static_cast<long long>(node.size());
        if (count < 0 || count > 64)
          throw InputError(name + "'s " + key + " declares " + std::to_string(count) +
                           " values; a calibration matrix holds at most 64. Check the calibration file.");
        node >> m;
      };
      cv::Mat K, D;
      readMatrix("camera_matrix", K);
      readMatrix("distortion_coefficients", D);
      if (K.empty()) readMatrix("K", K);
      if (D.empty()) readMatrix("D", D);
      if (K.rows != 3 || K.cols != 3) throw InputError(name + " has no 3x3 camera_matrix; check the calibration file.");
      K.convertTo(K, CV_64F);
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) c.K(r, k) = K.at<double>(r, k);
      if (!D.empty()) {
        D.convertTo(D, CV_64F);
        D = D.reshape(1, 1);
        for (int k = 0; k < std::min(5, D.cols); ++k) c.distortion[k] = D.at<double>(0, k);
      }
      int w = 0, h = 0;
      if (!fsx["image_width"].empty()) fsx["image_width"] >> w;
      if (!fsx["image_height"].empty()) fsx["image_height"] >> h;
      if (w > 0) c.width = w;
      if (h > 0) c.height = h;
    } catch (const InputError&) {
      throw;
    } catch (const std::exception&) {
      // cv::Exception, and what its parser lets through of the standard library's (found by fuzzing: a damaged YAML
      // matrix made FileStorage throw std::length_error, which ended the program).
      throw InputError(name + " is not a readable OpenCV calibration file; check its format.");
    }
    return finish(c, path);
  }
  const std::string text = readText(path, "camera");
  if (e == ".json") {
    if (const std::string why = jsonTextProblem(text, name); !why.empty()) throw InputError(why + ".");
    try {
      auto j = nlohmann::json::parse(text);
      if (j.contains("K")) {
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) c.K(r, k) = num(j["K"].at(r).at(k));
        if (j.contains("distortion"))
          for (std::size_t k = 0; k < std::min<std::size_t>(5, j["distortion"].size()); ++k) c.distortion[k] = num(j["distortion"][k]);
      } else if (j.contains("fx")) {
        c.K << num(j["fx"]), 0, num(j["cx"]), 0, num(j["fy"]), num(j["cy"]), 0, 0, 1;
        const char* keys[5] = {"k1", "k2", "p1", "p2", "k3"};
        for (int k = 0; k < 5; ++k)
          if (j.contains(keys[k])) c.distortion[k] = num(j[keys[k]]);
      } else {
        throw InputError(name + " has neither \"K\" nor \"fx\"; see \"File formats\" in the README.");
      }
      if (j.contains("width")) c.width = imageSize(num(j["width"]));
      if (j.contains("height")) c.height = imageSize(num(j["height"]));
    } catch (const InputError&) {
      throw;
    } catch (const std::exception&) {
      throw InputError(name + " is not a camera file this program reads: it needs \"K\" (3x3 numbers) or \"fx\", "
                       "\"fy\", \"cx\", \"cy\" as numbers; see \"File formats\" in the README.");
    }
    return finish(c, path);
  }
  // 3x3 text matrix.
  std::istringstream in(text);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      if (!(in >> c.K(r, k))) throw InputError(name + " does not hold a 3x3 camera matrix of numbers.");
  return finish(c, path);
}

void saveCamera(const Camera& c, const std::string& path) {
  const std::string e = ext(path);
  if (e == ".json") {
    nlohmann::json j;
    j["K"] = {{c.K(0, 0), c.K(0, 1), c.K(0, 2)}, {c.K(1, 0), c.K(1, 1), c.K(1, 2)}, {c.K(2, 0), c.K(2, 1), c.K(2, 2)}};
    j["distortion"] = c.distortion;
    j["width"] = c.width;
    j["height"] = c.height;
    writeFileAtomically(path, j.dump(2) + "\n");
    return;
  }
  cv::FileStorage fsx(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY | (e == ".xml" ? cv::FileStorage::FORMAT_XML : 0));
  cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) K.at<double>(r, k) = c.K(r, k);
  for (int k = 0; k < 5; ++k) D.at<double>(0, k) = c.distortion[k];
  fsx << "image_width" << c.width << "image_height" << c.height << "camera_matrix" << K << "distortion_coefficients" << D;
  writeFileAtomically(path, fsx.releaseAndGetString());
}

Pose loadPose(const std::string& path, double matrixUnitToMetre) {
  const std::string text = readText(path, "pose");
  const std::string name = fs::path(path).filename().string();
  Pose p;
  if (ext(path) == ".json") {
    try {
      auto j = nlohmann::json::parse(text);
      double unit = 1.0;
      if (j.contains("unit")) {
        auto u = j["unit"].get<std::string>();
        unit = u == "m" ? 1.0 : u == "cm" ? 0.01 : u == "mm" ? 0.001 : u == "dm" ? 0.1 : -1.0;
        if (unit < 0) throw InputError(name + ": unknown unit '" + u + "'; use m, cm or mm.");
      }
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) p.R(r, k) = j.at("R").at(r).at(k).get<double>();
        p.t[r] = j.at("t").at(r).get<double>() * unit;
      }
    } catch (const InputError&) {
      throw;
    } catch (const std::exception&) {
      throw InputError(name + " is not a pose file: it needs \"R\" (3x3) and \"t\" (3 numbers).");
    }
  } else {
    std::istringstream in(text);
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k)
        if (!(in >> M(r, k))) throw InputError(name + " does not hold a 4x4 matrix of numbers.");
    p.R = M.topLeftCorner<3, 3>();
    p.t = M.topRightCorner<3, 1>() * matrixUnitToMetre;
  }
  if (!p.R.allFinite() || (p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || p.R.determinant() < 0)
    throw InputError(name + ": R is not a rotation matrix (orthonormal, determinant +1); check the pose file.");
  // The organ lies within an arm's length of the scope: a translation beyond 10 m (1e308 overflowed the
  // registration's pixel casts) is a damaged file or a wrong unit.
  if (!p.t.allFinite() || p.t.norm() > kMaxPoseTranslationMetres)
    throw InputError(name + ": the translation t is not a number or beyond 10 m; check the pose file and its unit.");
  return p;
}

std::string poseToJson(const Pose& p) {
  nlohmann::json j;
  j["R"] = {{p.R(0, 0), p.R(0, 1), p.R(0, 2)}, {p.R(1, 0), p.R(1, 1), p.R(1, 2)}, {p.R(2, 0), p.R(2, 1), p.R(2, 2)}};
  j["t"] = {p.t.x(), p.t.y(), p.t.z()};
  j["unit"] = "m";
  return j.dump(2);
}

void savePose(const Pose& p, const std::string& path) { writeFileAtomically(path, poseToJson(p) + "\n"); }

cv::Mat3b undistortImage(const cv::Mat3b& image, const Camera& camera) {
  if (image.empty() || !camera.distorted()) return image;
  cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = camera.K(r, c);
  for (int i = 0; i < 5; ++i) D.at<double>(0, i) = camera.distortion[static_cast<std::size_t>(i)];
  cv::Mat3b out;
  cv::undistort(image, out, K, D, K);
  return out;
}

}  // namespace rehearse::imaging
