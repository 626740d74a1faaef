#pragma once
// What happens at a step, as typed values with their words (issue 63). The kinds are what code emits, compares and
// counts; the words are what snapshots, recordings, reports and the review carry ("grasp", "vessel cut", "cut through
// label 3", "artery torn"). The words are the recordings' format: they never change, and a kind is read back from its
// word (eventKind). The counts are made in one place (EventCounts), for the gesture's result, a session's metrics and
// the rehearsal page.
#include <string>
#include <string_view>
#include <vector>

namespace rehearse::simcore {

enum class EventKind {
  Grasp,                 ///< "grasp": the jaws closed on tissue
  Release,               ///< "release"
  Slip,                  ///< "slip": the tissue slipped out of the jaws
  Cut,                   ///< "cut": a blade's stroke changed the mesh
  CutThroughLabel,       ///< "cut through label N", once per label the stroke went through
  StructureCut,          ///< "<structure> cut" ("portal vein cut", "bile duct cut", "ligament cut", "tumour cut")
  VesselCut,             ///< "vessel cut": a blood vessel of any kind was cut (what the metrics count)
  TumourMarginBreached,  ///< "tumour margin breached"
  Clip,                  ///< "clip": a clip was left
  ClipMisplaced,         ///< "clip misplaced"
  Burn,                  ///< "burn": the cautery hook burnt tissue
  EnergyOnStructure,     ///< "energy on structure": the hook's energy on a named structure (what the metrics count)
  EnergyOnNamedStructure,  ///< "energy on <structure>" ("energy on artery"), beside it
  Bleeding,              ///< "bleeding": a cut vessel bleeds
  BleedingStopped,       ///< "bleeding stopped"
  Tear,                  ///< "tear": the tissue tore
  StructureTorn,         ///< "<structure> torn" ("artery torn", "ligament torn")
  VesselTorn,            ///< "vessel torn": a blood vessel of any kind tore
  AttachmentTorn,        ///< "attachment torn"
  ForceOverThreshold,    ///< "force over threshold": the review's timeline (a session's metrics add it)
  IncorrectAction,       ///< "incorrect action: <rule>": the review's timeline (the trainer's rules)
  Other,                 ///< a word no kind has (a metric's "incorrect action: ...", a newer build's event)
};

/// The word of a kind that has one ("grasp", "vessel cut"); "" for CutThroughLabel, StructureCut, StructureTorn,
/// EnergyOnNamedStructure, IncorrectAction and Other, whose words name what (cutThroughLabelWord, structureEventWord,
/// incorrectActionWord).
const char* eventWord(EventKind kind);
/// "cut through label N".
std::string cutThroughLabelWord(int label);
/// "<structure> cut", "<structure> torn" or "energy on <structure>" (kind StructureCut, StructureTorn or
/// EnergyOnNamedStructure; `structure` as structureKindName).
std::string structureEventWord(EventKind kind, const std::string& structure);
/// "incorrect action: <rule>".
std::string incorrectActionWord(const std::string& rule);
/// The kind of an event's word (Other when no kind has it).
EventKind eventKind(std::string_view word);
/// The label a "cut through label N" word names; -1 for any other word.
int cutLabelOf(std::string_view word);

/// The events of a run, counted in one place.
struct EventCounts {
  int grasps = 0, releases = 0, slips = 0, cuts = 0, vesselCuts = 0, clips = 0, misplacedClips = 0, burns = 0,
      energyOnStructures = 0, bleedings = 0, bleedingsStopped = 0, tears = 0, attachmentsTorn = 0;
  /// Adds one step's events.
  void add(const std::vector<std::string>& events);
};

}  // namespace rehearse::simcore
