#pragma once
// A case (everything a user made) as one SQLite file (SQLite's own library, no Qt: the command line and the GUI-less
// build read and write what the GUI saves), written atomically: a new
// database is written beside the target, flushed to disk, then renamed over it, so killing the program
// at any moment leaves either the previous file or the new one, never a mix.
//
// Schema (version 2): meta(key, value) with schema_version, app_version, name, saved_utc;
// parts(name, format, data, sha256, saved_utc): one row per part (volume as binary VTU, frame as PNG,
// camera, pose, attachments, material, contour, elastic fit and ground truth as JSON) with the SHA-256 of its data. A
// part that cannot be decoded, or whose data no longer matches its checksum, is reported on its own; the
// other parts still open.
// The precomputed model's responses (issue 37) are kept as the part precomputed_responses (8 bytes of their key,
// simcore::precomputeKey, then PrecomputedElasticity::toBytes): a cache, used when the organ, its attachments, material
// and gravity give the same key again, and rebuilt otherwise; responses over 512 MB are not kept (SQLite's blobs stop
// at 1 GB), they are built again when the case opens.
// History: 1, the first (no checksums; no elastic_fit part, no model_vertices in the contour). Opening
// an older case migrates it in memory (schema 1: parts read without a checksum); saving writes the current
// schema. A newer schema than this build knows is refused with a sentence, so an older Rehearse never
// re-saves a case without the parts it does not know.
#include <rehearse/app/case.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace rehearse::app {

inline constexpr int kCaseSchemaVersion = 2;
inline constexpr const char* kCaseSuffix = "rehearse";

/// Writes `c` to `path` atomically. The rehearsals recorded in `recordingsFrom` (the case file the case was
/// opened from or last saved to; empty: none) are carried into it, every session with its identity: a Save As
/// carries them to the new file, a save over the same file keeps them. Throws std::runtime_error with one
/// sentence; the file at `path` is then unchanged.
/// `responseKey`: the precomputed responses in simcore::ResponseCache to keep with the case (0: none).
void saveCaseFile(const Case& c, const std::string& path, const std::string& recordingsFrom = {},
                  std::uint64_t responseKey = 0);

/// Reads a case file. Parts that cannot be read are described in `notes` and left empty; stored precomputed responses
/// are offered to simcore::ResponseCache (the body that needs them checks them). Throws
/// std::runtime_error with one sentence when the file is not a readable case at all.
Case loadCaseFile(const std::string& path, std::vector<std::string>* notes = nullptr);

/// True when `path` looks like a case file (SQLite header), without opening it as a database.
bool isCaseFile(const std::string& path);

/// A case as the command line takes it: a case file (.rehearse, what the GUI saves) or a case folder (what `rehearse
/// phantom --out DIR` writes, casefolder.hpp). Parts that could not be read are described in `notes`. Throws
/// std::runtime_error (or rehearse::InputError) with one sentence when `path` is neither.
Case loadCase(const std::string& path, std::vector<std::string>* notes = nullptr);

}  // namespace rehearse::app
