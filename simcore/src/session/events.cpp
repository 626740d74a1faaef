// Events as typed values with their words (events.hpp).
#include "rehearse/simcore/session/events.hpp"

#include <charconv>

namespace rehearse::simcore {
namespace {
constexpr std::string_view kCutThroughLabel = "cut through label ";
constexpr EventKind kWorded[] = {EventKind::Grasp,           EventKind::Release,       EventKind::Slip,
                                 EventKind::Cut,             EventKind::VesselCut,     EventKind::TumourMarginBreached,
                                 EventKind::Clip,            EventKind::ClipMisplaced, EventKind::Burn,
                                 EventKind::EnergyOnStructure, EventKind::Bleeding,    EventKind::BleedingStopped,
                                 EventKind::Tear,            EventKind::VesselTorn,    EventKind::AttachmentTorn,
                                 EventKind::ForceOverThreshold};
constexpr std::string_view kEnergyOn = "energy on ", kIncorrectAction = "incorrect action";
bool endsWith(std::string_view s, std::string_view tail) {
  return s.size() > tail.size() && s.substr(s.size() - tail.size()) == tail;
}
}  // namespace

const char* eventWord(EventKind kind) {
  switch (kind) {
    case EventKind::Grasp: return "grasp";
    case EventKind::Release: return "release";
    case EventKind::Slip: return "slip";
    case EventKind::Cut: return "cut";
    case EventKind::VesselCut: return "vessel cut";
    case EventKind::TumourMarginBreached: return "tumour margin breached";
    case EventKind::Clip: return "clip";
    case EventKind::ClipMisplaced: return "clip misplaced";
    case EventKind::Burn: return "burn";
    case EventKind::EnergyOnStructure: return "energy on structure";
    case EventKind::Bleeding: return "bleeding";
    case EventKind::BleedingStopped: return "bleeding stopped";
    case EventKind::Tear: return "tear";
    case EventKind::VesselTorn: return "vessel torn";
    case EventKind::AttachmentTorn: return "attachment torn";
    case EventKind::ForceOverThreshold: return "force over threshold";
    case EventKind::EnergyOnNamedStructure:
    case EventKind::IncorrectAction:
    case EventKind::CutThroughLabel:
    case EventKind::StructureCut:
    case EventKind::StructureTorn:
    case EventKind::Other: break;
  }
  return "";
}

std::string cutThroughLabelWord(int label) { return std::string(kCutThroughLabel) + std::to_string(label); }

std::string structureEventWord(EventKind kind, const std::string& structure) {
  if (kind == EventKind::EnergyOnNamedStructure) return std::string(kEnergyOn) + structure;
  return structure + (kind == EventKind::StructureTorn ? " torn" : " cut");
}

std::string incorrectActionWord(const std::string& rule) { return std::string(kIncorrectAction) + ": " + rule; }

EventKind eventKind(std::string_view word) {
  for (EventKind k : kWorded)
    if (word == eventWord(k)) return k;
  if (cutLabelOf(word) >= 0) return EventKind::CutThroughLabel;
  if (word.substr(0, kEnergyOn.size()) == kEnergyOn && word.size() > kEnergyOn.size()) return EventKind::EnergyOnNamedStructure;
  if (word.substr(0, kIncorrectAction.size()) == kIncorrectAction) return EventKind::IncorrectAction;
  if (endsWith(word, " cut")) return EventKind::StructureCut;
  if (endsWith(word, " torn")) return EventKind::StructureTorn;
  return EventKind::Other;
}

int cutLabelOf(std::string_view word) {
  if (word.substr(0, kCutThroughLabel.size()) != kCutThroughLabel) return -1;
  const std::string_view digits = word.substr(kCutThroughLabel.size());
  int label = -1;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), label);
  return error == std::errc() && end == digits.data() + digits.size() && label >= 0 ? label : -1;
}

void EventCounts::add(const std::vector<std::string>& events) {
  for (const auto& e : events) switch (eventKind(e)) {
      case EventKind::Grasp: ++grasps; break;
      case EventKind::Release: ++releases; break;
      case EventKind::Slip: ++slips; break;
      case EventKind::Cut: ++cuts; break;
      case EventKind::VesselCut: ++vesselCuts; break;
      case EventKind::Clip: ++clips; break;
      case EventKind::ClipMisplaced: ++misplacedClips; break;
      case EventKind::Burn: ++burns; break;
      case EventKind::EnergyOnStructure: ++energyOnStructures; break;
      case EventKind::Bleeding: ++bleedings; break;
      case EventKind::BleedingStopped: ++bleedingsStopped; break;
      case EventKind::Tear: ++tears; break;
      case EventKind::AttachmentTorn: ++attachmentsTorn; break;
      default: break;
    }
}

}  // namespace rehearse::simcore
