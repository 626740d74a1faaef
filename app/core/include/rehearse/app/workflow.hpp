#pragma once
// The workflow: the steps of a case in the order they are worked (README.md, "Working a case"), what each needs, whether it
// is done, and which comes next. Counts come from the table (kSteps), never from literals: a new step
// (appearance, rehearsal) is one row here and one page class in ui/.
#include "rehearse/app/case.hpp"

#include <array>
#include <string>

namespace rehearse::app {

enum class Step { Mesh = 0, Frame, Contour, Rigid, Elastic, Appearance, Rehearse };

struct StepInfo {
  Step step;
  const char* title;      ///< "Organ mesh"
  bool available;         ///< false: shown greyed ("comes in a later version")
};

inline constexpr std::array<StepInfo, 7> kSteps = {{{Step::Mesh, "Organ mesh", true},
                                                    {Step::Frame, "Endoscope frame", true},
                                                    {Step::Contour, "Contour", true},
                                                    {Step::Rigid, "Rigid alignment", true},
                                                    {Step::Elastic, "Elastic fit", true},
                                                    {Step::Appearance, "Appearance", true},
                                                    {Step::Rehearse, "Rehearse", true}}};
inline constexpr int kStepCount = static_cast<int>(kSteps.size());
inline constexpr int index(Step s) { return static_cast<int>(s); }

/// True when the case holds what the step produces.
bool stepDone(const Case& c, Step s);
/// The first available step that is not done; kStepCount when all are.
int nextStep(const Case& c);
/// Why a step cannot run yet: "" when it can, else what is missing, as a phrase ("a contour (step 3): ...").
std::string missingFor(const Case& c, Step s);

}  // namespace rehearse::app
