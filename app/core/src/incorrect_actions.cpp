// The trainer's incorrect actions: rules from JSON and their finder over a replay's steps (incorrect_actions.hpp).
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/app/incorrect_actions.hpp>
#include <rehearse/text_input.hpp>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rehearse::app {

bool ActionView::sees(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d c = rotation * (p - from);
  if (!(c.z() > 0)) return false;
  const Eigen::Vector2d q = camera.project(c);
  return q.allFinite() && q.x() >= 0 && q.y() >= 0 && q.x() < camera.width && q.y() < camera.height;
}

const std::vector<std::pair<std::string, std::string>>& actionRuleNames() {
  static const std::vector<std::pair<std::string, std::string>> names = {
      {"vessel_cut_without_clips", "vessel cut without clips"},
      {"energy_on_structure", "energy on a named structure"},
      {"force_over_limit", "force over the limit"},
      {"tear", "tissue torn"},
      {"clip_misplaced", "clip misplaced"},
      {"outside_view", "instrument used outside the view"}};
  return names;
}

namespace {

using nlohmann::json;

Eigen::Vector3d vector3(const json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
    throw std::runtime_error("the view's " + what + " must be [x, y, z] in metres");
  Eigen::Vector3d v(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
  if (!v.allFinite()) throw std::runtime_error("the view's " + what + " is not finite");
  return v;
}

ActionView parseView(const json& j) {
  if (!j.is_object())
    throw std::runtime_error(
        "the incorrect actions' view must be {\"fx\", \"fy\", \"cx\", \"cy\", \"width\", \"height\"}");
  ActionView v;
  auto number = [&](const char* key) {
    if (!j.contains(key) || !j[key].is_number())
      throw std::runtime_error(std::string("the incorrect actions' view needs a number '") + key + "'");
    return j[key].get<double>();
  };
  for (const auto& [key, value] : j.items())
    if (key != "fx" && key != "fy" && key != "cx" && key != "cy" && key != "width" && key != "height" &&
        key != "from" && key != "to")
      throw std::runtime_error("the incorrect actions' view has '" + key +
                               "'; known: fx, fy, cx, cy, width, height, from, to");
  v.camera.K << number("fx"), 0, number("cx"), 0, number("fy"), number("cy"), 0, 0, 1;
  const double w = number("width"), h = number("height");
  if (!(w >= 1 && w <= 16384 && h >= 1 && h <= 16384) || w != std::floor(w) || h != std::floor(h))
    throw std::runtime_error("the incorrect actions' view needs a whole image size of 1 to 16384 pixels");
  v.camera.width = static_cast<int>(w);
  v.camera.height = static_cast<int>(h);
  if (const std::string p = v.camera.problem(); !p.empty())
    throw std::runtime_error("the incorrect actions' view: " + p);
  if (j.contains("from")) v.from = vector3(j["from"], "from");
  if (j.contains("to")) {
    const Eigen::Vector3d z = vector3(j["to"], "to") - v.from;
    if (!(z.norm() > 0)) throw std::runtime_error("the incorrect actions' view looks from a point to itself");
    // The camera looks along z; the body's +y points down the image as far as it can (x right, y down).
    const Eigen::Vector3d zc = z.normalized();
    Eigen::Vector3d down = Eigen::Vector3d::UnitY() - zc.y() * zc;
    if (down.norm() < 1e-6) down = Eigen::Vector3d::UnitZ() - zc.z() * zc;
    const Eigen::Vector3d yc = down.normalized(), xc = yc.cross(zc);
    v.rotation.row(0) = xc.transpose();
    v.rotation.row(1) = yc.transpose();
    v.rotation.row(2) = zc.transpose();
  }
  return v;
}

json viewJson(const ActionView& v) {
  json j = {{"fx", v.camera.fx()}, {"fy", v.camera.fy()},     {"cx", v.camera.cx()},
            {"cy", v.camera.cy()}, {"width", v.camera.width}, {"height", v.camera.height}};
  if (!v.rotation.isIdentity(0) || v.from != Eigen::Vector3d::Zero()) {
    const Eigen::Vector3d to = v.from + v.rotation.row(2).transpose();
    j["from"] = {v.from.x(), v.from.y(), v.from.z()};
    j["to"] = {to.x(), to.y(), to.z()};
  }
  return j;
}

}  // namespace

ActionRules parseActionRules(const std::string& text) {
  ActionRules r;
  if (text.empty()) return r;
  if (const std::string why = jsonTextProblem(text, "the incorrect-action rules"); !why.empty())
    throw std::runtime_error(why);
  json j;
  try {
    j = json::parse(text);
  } catch (const std::exception&) {
    throw std::runtime_error("the incorrect actions are not JSON (expected {\"tear\": true, ...})");
  }
  if (!j.is_object()) throw std::runtime_error("the incorrect actions must be a JSON object of rules");
  auto flag = [](const json& v, const std::string& key) {
    if (!v.is_boolean()) throw std::runtime_error("the incorrect action '" + key + "' must be true or false");
    return v.get<bool>();
  };
  for (const auto& [key, value] : j.items()) {
    if (key == "vessel_cut_without_clips")
      r.vesselCutWithoutClips = flag(value, key);
    else if (key == "energy_on_structure")
      r.energyOnStructure = flag(value, key);
    else if (key == "tear")
      r.tear = flag(value, key);
    else if (key == "clip_misplaced")
      r.clipMisplaced = flag(value, key);
    else if (key == "outside_view")
      r.outsideView = flag(value, key);
    else if (key == "view")
      r.view = parseView(value);
    else if (key == "force_over_limit") {
      if (value.is_boolean()) {
        r.forceOverLimit = value.get<bool>();
        continue;
      }
      if (!value.is_object())
        throw std::runtime_error(
            "the incorrect action 'force_over_limit' must be false or {\"limit_n\": 10, \"longer_than_s\": 1}");
      for (const auto& [k, x] : value.items()) {
        if (k != "limit_n" && k != "longer_than_s")
          throw std::runtime_error("'force_over_limit' has '" + k + "'; known: limit_n, longer_than_s");
        if (!x.is_number() || !(x.get<double>() >= 0) || !std::isfinite(x.get<double>()) ||
            (k == "limit_n" && !(x.get<double>() > 0)))
          throw std::runtime_error(
              "'force_over_limit' " + k +
              (k == "limit_n" ? " must be a positive number of newtons" : " must be a number of seconds, 0 or more"));
        (k == "limit_n" ? r.forceLimitN : r.forceLongerThanS) = x.get<double>();
      }
    } else {
      std::string known;
      for (const auto& [name, words] : actionRuleNames()) known += name + ", ";
      throw std::runtime_error("the incorrect actions name an unknown rule '" + key + "' (known: " + known + "view)");
    }
  }
  return r;
}

std::string actionRulesJson(const ActionRules& r) {
  const ActionRules d;
  json j = json::object();
  if (r.vesselCutWithoutClips != d.vesselCutWithoutClips) j["vessel_cut_without_clips"] = r.vesselCutWithoutClips;
  if (r.energyOnStructure != d.energyOnStructure) j["energy_on_structure"] = r.energyOnStructure;
  if (!r.forceOverLimit)
    j["force_over_limit"] = false;
  else if (r.forceLimitN != d.forceLimitN || r.forceLongerThanS != d.forceLongerThanS)
    j["force_over_limit"] = {{"limit_n", r.forceLimitN}, {"longer_than_s", r.forceLongerThanS}};
  if (r.tear != d.tear) j["tear"] = r.tear;
  if (r.clipMisplaced != d.clipMisplaced) j["clip_misplaced"] = r.clipMisplaced;
  if (r.outsideView != d.outsideView) j["outside_view"] = r.outsideView;
  if (r.view) j["view"] = viewJson(*r.view);
  return j.empty() ? std::string() : j.dump();
}

std::string cameraViewJson(const imaging::Camera& camera) {
  ActionView v;
  v.camera = camera;
  v.camera.distortion = {};
  return viewJson(v).dump();
}

std::optional<std::string> IncorrectActionFinder::notCounted(const std::string& rule) const {
  const bool on = rule == "vessel_cut_without_clips" ? rules_.vesselCutWithoutClips
                  : rule == "energy_on_structure"    ? rules_.energyOnStructure
                  : rule == "force_over_limit"       ? rules_.forceOverLimit
                  : rule == "tear"                   ? rules_.tear
                  : rule == "clip_misplaced"         ? rules_.clipMisplaced
                  : rule == "outside_view"           ? rules_.outsideView
                                                     : false;
  if (!on) return "the scene does not count this as an incorrect action";
  if (rule == "outside_view" && !rules_.view)
    return "the session recorded no view (camera): where the instrument was in it is not known";
  return std::nullopt;
}

std::vector<IncorrectAction> IncorrectActionFinder::step(const StepFacts& s) {
  std::vector<IncorrectAction> out;
  auto add = [&](const char* rule, std::string what) {
    if (!notCounted(rule)) out.push_back({rule, s.step, s.time, std::move(what)});
  };
  static const std::vector<std::string> none;
  const auto& events = s.events ? *s.events : none;
  auto has = [&](simcore::EventKind k) {
    return std::any_of(events.begin(), events.end(), [k](const std::string& e) { return simcore::eventKind(e) == k; });
  };
  // A cut that opened a bleeding stump: the vessel had no clip behind the cut.
  if (has(simcore::EventKind::Bleeding) && has(simcore::EventKind::Cut))
    add("vessel_cut_without_clips", "a vessel was cut where no clip closes it: it bleeds");
  for (const auto& e : events) {
    const simcore::EventKind kind = simcore::eventKind(e);
    if (kind == simcore::EventKind::EnergyOnNamedStructure) add("energy_on_structure", e);
    if (kind == simcore::EventKind::Tear) {  // one over-pull tears element after element: one action, however many tears follow it
      constexpr double kTearSpell = 0.5;
      if (s.time - lastTear_ > kTearSpell) add("tear", "tissue was pulled past the strain its material tears at");
      lastTear_ = s.time;
    }
    if (kind == simcore::EventKind::ClipMisplaced) add("clip_misplaced", "a clip was left on no vessel or duct, or not across all of it");
  }
  // The force above the limit for longer than the rule allows: once per spell.
  if (s.force > rules_.forceLimitN) {
    if (overSince_ < 0) overSince_ = s.time, overCounted_ = false;
    if (!overCounted_ && s.time - overSince_ >= rules_.forceLongerThanS) {
      overCounted_ = true;
      char buf[160];
      std::snprintf(buf, sizeof buf, "the tool's force stayed above %.3g N for %.3g s (now %.3g N)", rules_.forceLimitN,
                    s.time - overSince_, s.force);
      add("force_over_limit", buf);
    }
  } else {
    overSince_ = -1;
  }
  // An instrument acting (holding, cutting, burning, leaving a clip) where the camera does not see it: once per spell.
  const bool acting = s.toolPresent && (s.holding || s.cutting || s.energy || has(simcore::EventKind::Clip));
  const bool outside = acting && rules_.view && !rules_.view->sees(s.tip);
  if (outside && !outside_) {
    const char* doing = s.cutting ? "cutting" : s.energy ? "burning" : s.holding ? "holding tissue" : "leaving a clip";
    add("outside_view", std::string("the instrument was ") + doing + " outside the view");
  }
  outside_ = outside;
  found_.insert(found_.end(), out.begin(), out.end());
  return out;
}

}  // namespace rehearse::app
