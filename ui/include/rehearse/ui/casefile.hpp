#pragma once
// A case (everything a user made) as one SQLite file through Qt SQL, written atomically: a new
// database is written beside the target, flushed to disk, then renamed over it, so killing the program
// at any moment leaves either the previous file or the new one, never a mix.
//
// Schema (version 1): meta(key, value) with schema_version, app_version, name, saved_utc;
// parts(name, format, data, saved_utc): one row per part (volume as binary VTU, frame as PNG, camera,
// pose, attachments and ground truth as JSON). A part that cannot be decoded is reported on its own;
// the other parts still open.
#include "phantom/phantom.hpp"

#include <QString>
#include <QStringList>

namespace rehearse::ui {

inline constexpr int kCaseSchemaVersion = 1;
inline constexpr const char* kCaseSuffix = "rehearse";

/// Writes `c` to `path` atomically. Throws std::runtime_error with one sentence; the file at `path`
/// is then unchanged.
void saveCaseFile(const phantom::Case& c, const QString& path);

/// Reads a case file. Parts that cannot be read are described in `notes` and left empty. Throws
/// std::runtime_error with one sentence when the file is not a readable case at all.
phantom::Case loadCaseFile(const QString& path, QStringList* notes = nullptr);

/// True when `path` looks like a case file (SQLite header), without opening it as a database.
bool isCaseFile(const QString& path);

}  // namespace rehearse::ui
