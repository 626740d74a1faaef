#include "rehearse/app/workflow.hpp"

namespace rehearse::app {

bool stepDone(const Case& c, Step s) {
  switch (s) {
    case Step::Mesh: return !c.organ->empty();
    case Step::Frame: return !c.frame.empty() && c.camera.problem().empty();
    case Step::Contour: return imaging::contourProblem(c.contour).empty();
    // Aligned by hand, or placed by a completed fit (which finds the pose too): not "(next)" after the fit.
    case Step::Rigid: return c.poseDetermined();
    case Step::Elastic: return c.hasFit();
    case Step::Appearance: return c.appearanceCurrent();
    default: return false;
  }
}

int nextStep(const Case& c) {
  for (const auto& s : kSteps)
    if (s.available && !stepDone(c, s.step)) return index(s.step);
  return kStepCount;
}

std::string missingFor(const Case& c, Step s) {
  if (index(s) > index(Step::Mesh) && !stepDone(c, Step::Mesh)) return "an organ mesh (step 1)";
  if (index(s) > index(Step::Frame) && !stepDone(c, Step::Frame)) return "a frame with its camera (step 2)";
  // The appearance needs the organ placed over the frame, not the contour it was fitted to.
  if (s == Step::Appearance) return c.hasPose ? std::string() : "the organ placed over the frame (step 4)";
  if (index(s) > index(Step::Contour) && !stepDone(c, Step::Contour)) {
    std::string why = imaging::contourProblem(c.contour);  // a sentence; here a phrase ("The fit needs %1.")
    if (!why.empty() && why.back() == '.') why.pop_back();
    return "a contour (step 3): " + why;
  }
  if (index(s) > index(Step::Rigid) && !c.hasPose) return "a rigid alignment (step 4)";
  return {};
}

}  // namespace rehearse::app
