#include <rehearse/imaging/appearance.hpp>
#include <rehearse/text_input.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace rehearse::imaging {

double Appearance::falloffAt(const Eigen::Vector3d& p) const {
  if (falloff == 0) return 1.0;
  const double norm = p.norm();
  if (!(p.z() > 0) || !(norm > 0)) return 0.0;
  return std::pow(p.z() / norm, falloff);
}

void Appearance::terms(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double& diffuse, double& specular) const {
  diffuse = specular = 0;
  const Eigen::Vector3d toLight = lightPosition - p;
  const double r2 = std::max(toLight.squaredNorm(), 1e-12);
  const Eigen::Vector3d l = toLight / std::sqrt(r2);
  const Eigen::Vector3d v = (-p).normalized();
  const double cosI = n.dot(l);
  if (cosI <= 0) return;
  const double cosR = std::max(n.dot(v), 1e-3);
  const Eigen::Vector3d h = (l + v).normalized();
  const double alpha = std::acos(std::clamp(n.dot(h), -1.0, 1.0));
  const double f = falloffAt(p);
  diffuse = f * cosI / r2;
  specular = f * std::exp(-alpha * alpha / (2 * roughness * roughness)) / (r2 * cosR);
}

double reshadeTrust(double explained) {
  constexpr double kPoor = 0.5, kEarned = 0.9;
  if (!std::isfinite(explained)) return 0;
  return std::clamp((explained - kPoor) / (kEarned - kPoor), 0.0, 1.0);
}

int trustPercent(double trust) {
  if (!(trust > 0)) return 0;
  if (trust >= 1) return 100;
  return std::clamp(static_cast<int>(std::lround(100 * trust)), 1, 99);
}

int explainedPercent(double explained) {
  return std::isfinite(explained) ? std::clamp(static_cast<int>(std::floor(100 * explained + 1e-9)), 0, 100) : 0;
}

Reshading Reshading::of(double explained, bool textureOnly) {
  return textureOnly ? Reshading{true, 0.0} : Reshading{false, reshadeTrust(explained)};
}

Eigen::Vector3d Appearance::secondSource(const Eigen::Vector3d& n) const {
  return kr * std::max(0.0, n.dot(roomDirection)) + ka;
}

Eigen::Vector3d Appearance::shade(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
  double d, s;
  terms(p, n, d, s);
  return kd * d + ks * s + secondSource(n);
}

std::string appearanceProblem(const Appearance& a, bool zeroRoughness) {
  auto inRange = [](const Eigen::Vector3d& v, double hi) { return v.allFinite() && v.minCoeff() >= 0 && v.maxCoeff() <= hi; };
  if (!inRange(a.kd, 100) || !inRange(a.ks, 100)) return "k_d and k_s must be between 0 and 100 in every channel";
  if (!a.lightPosition.allFinite() || a.lightPosition.norm() > 10) return "the light must be within 10 m of the camera";
  if (!inRange(a.kr, 100) || !inRange(a.ka, 100)) return "k_r and k_a must be between 0 and 100 in every channel";
  if (!a.roomDirection.allFinite() || (a.roomDirection.squaredNorm() > 0 && std::abs(a.roomDirection.norm() - 1) > 1e-6) ||
      (a.roomDirection.squaredNorm() == 0 && a.kr.maxCoeff() > 0))
    return "the distant light's direction must be a unit vector (towards the light, camera frame)";
  if (!(std::isfinite(a.roughness) && a.roughness <= 10 && (a.roughness > 0 || (zeroRoughness && a.roughness == 0))))
    return "the roughness must be a positive angle of at most 10 rad";
  if (!(a.falloff >= 0 && a.falloff <= 200)) return "falloff (the n of cos^n off the scope's axis) must be between 0 and 200";
  return {};
}

Appearance loadAppearance(const std::string& path, AppearanceVerdict* verdict) {
  std::string text, why;
  if (!readTextInput(path, text, why, std::size_t{1} << 20)) throw InputError("The appearance file " + why + ".");
  const std::string name = std::filesystem::path(path).filename().string();
  if (const std::string deep = jsonTextProblem(text, name); !deep.empty()) throw InputError(deep + ".");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(name + " is not valid JSON (at byte " + std::to_string(e.byte) + "); write it again.");
  }
  if (!j.is_object())
    throw InputError(name + " is not an appearance file: it needs light_position, kd, ks and roughness.");
  // Each field read on its own, so that the sentence names the one that is missing or not what it must be.
  auto number = [&](const nlohmann::json& o, const char* key, const std::string& what) {
    if (!o.contains(key) || !o.at(key).is_number()) throw InputError(name + ": \"" + key + "\" must be " + what + ".");
    return o.at(key).get<double>();
  };
  auto triple = [&](const char* key, const char* what) {
    if (!j.contains(key) || !j.at(key).is_array() || j.at(key).size() != 3 ||
        !std::all_of(j.at(key).begin(), j.at(key).end(), [](const nlohmann::json& v) { return v.is_number(); }))
      throw InputError(name + ": \"" + key + "\" must be three numbers (" + what + ").");
    return Eigen::Vector3d(j.at(key)[0].get<double>(), j.at(key)[1].get<double>(), j.at(key)[2].get<double>());
  };
  Appearance a;
  a.lightPosition = triple("light_position", "the light's position in the camera frame, metres");
  a.kd = triple("kd", "the diffuse reflectance, red, green, blue");
  a.ks = triple("ks", "the specular reflectance, red, green, blue");
  a.roughness = number(j, "roughness", "a number (the specular lobe's width, radians)");
  // Files from before the laparoscope's fall-off: an isotropic light.
  a.falloff = j.contains("falloff") ? number(j, "falloff", "a number (the n of cos^n off the scope's axis)") : 0.0;
  // A second source (files without one, or from before it: none).
  if (j.contains("distant_light")) {
    const auto& d = j.at("distant_light");
    auto bad = [&] {
      return InputError(name + ": \"distant_light\" must be {\"direction\": three numbers (unit, towards the light, camera " +
                        "frame), \"kr\": three numbers (its diffuse reflection, red, green, blue)}.");
    };
    auto three = [&](const char* key) {
      if (!d.is_object() || !d.contains(key) || !d.at(key).is_array() || d.at(key).size() != 3 ||
          !std::all_of(d.at(key).begin(), d.at(key).end(), [](const nlohmann::json& v) { return v.is_number(); }))
        throw bad();
      return Eigen::Vector3d(d.at(key)[0].get<double>(), d.at(key)[1].get<double>(), d.at(key)[2].get<double>());
    };
    a.roomDirection = three("direction");
    a.kr = three("kr");
  }
  if (j.contains("ambient")) a.ka = triple("ambient", "the ambient term's diffuse reflection, red, green, blue");
  if (const std::string problem = appearanceProblem(a); !problem.empty()) throw InputError(name + ": " + problem + ".");
  if (verdict) {
    *verdict = {};
    if (j.contains("fit")) {
      const auto& f = j.at("fit");
      if (!f.is_object())
        throw InputError(name + ": \"fit\" must be what a fit said of itself: {\"explained\": share, \"reshade\": true or false}.");
      verdict->known = true;
      verdict->explained = number(f, "explained", "the share of the shading the fit explained, a number between 0 and 1");
      if (!f.contains("reshade") || !f.at("reshade").is_boolean())
        throw InputError(name + ": the fit's \"reshade\" must be true or false.");
      verdict->reshade = f.at("reshade").get<bool>();
      if (f.contains("said") && f.at("said").is_string()) verdict->said = f.at("said").get<std::string>();
      if (!(verdict->explained >= 0 && verdict->explained <= 1))
        throw InputError(name + ": the fit's explained share must be between 0 and 1.");
    }
  }
  return a;
}

void saveAppearance(const Appearance& a, const std::string& path, const AppearanceVerdict& verdict) {
  nlohmann::json j;
  j["light_position"] = {a.lightPosition.x(), a.lightPosition.y(), a.lightPosition.z()};
  j["kd"] = {a.kd.x(), a.kd.y(), a.kd.z()};
  j["ks"] = {a.ks.x(), a.ks.y(), a.ks.z()};
  j["roughness"] = a.roughness;
  j["falloff"] = a.falloff;
  if (a.hasDistantLight())
    j["distant_light"] = {{"direction", {a.roomDirection.x(), a.roomDirection.y(), a.roomDirection.z()}},
                          {"kr", {a.kr.x(), a.kr.y(), a.kr.z()}}};
  if (a.hasAmbient()) j["ambient"] = {a.ka.x(), a.ka.y(), a.ka.z()};
  if (verdict.known)
    j["fit"] = {{"explained", verdict.explained}, {"reshade", verdict.reshade}, {"said", verdict.said}};
  writeFileAtomically(path, j.dump(2) + "\n");
}

}  // namespace rehearse::imaging
