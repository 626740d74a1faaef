#pragma once
// A case as a folder of ordinary files (what `rehearse phantom --out DIR` writes and `rehearse open DIR`
// reads): case.json (manifest and ground truth), organ.vtu and organ.msh (volume), organ_surface.obj,
// vessels_surface.obj, camera.yaml, frame.png, pose.json and appearance.json (ground truth),
// attachments.json. The case file (one SQLite file) is casefile.hpp; loadCase there takes either.
#include "rehearse/app/case.hpp"

#include <string>
#include <vector>

namespace rehearse::app {

/// Writes `c` in `dir` (created if needed). Throws rehearse::InputError with one sentence.
void writeCaseDirectory(const Case& c, const std::string& dir);

/// Reads a case directory written by writeCaseDirectory. Missing optional parts are reported in `notes`.
/// Throws rehearse::InputError or simcore::MeshError with one sentence.
Case loadCaseDirectory(const std::string& dir, std::vector<std::string>* notes = nullptr);

}  // namespace rehearse::app
