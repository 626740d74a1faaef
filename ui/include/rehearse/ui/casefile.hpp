#pragma once
// The case file (rehearse/app/casefile.hpp, below the GUI) with Qt's paths and notes, for the GUI's callers.
#include <rehearse/app/casefile.hpp>

#include <QFile>
#include <QString>
#include <QStringList>

#include <cstdint>

namespace rehearse::ui {

using app::kCaseSchemaVersion;
using app::kCaseSuffix;

inline std::string localPath(const QString& path) { return QFile::encodeName(path).toStdString(); }

/// app::saveCaseFile with Qt's paths.
inline void saveCaseFile(const app::Case& c, const QString& path, const QString& recordingsFrom = {},
                         std::uint64_t responseKey = 0) {
  app::saveCaseFile(c, localPath(path), recordingsFrom.isEmpty() ? std::string() : localPath(recordingsFrom),
                    responseKey);
}

/// app::loadCaseFile with Qt's path and notes.
inline app::Case loadCaseFile(const QString& path, QStringList* notes = nullptr) {
  std::vector<std::string> said;
  app::Case c = app::loadCaseFile(localPath(path), notes ? &said : nullptr);
  if (notes)
    for (const auto& n : said) *notes << QString::fromStdString(n);
  return c;
}

inline bool isCaseFile(const QString& path) { return !path.isEmpty() && app::isCaseFile(localPath(path)); }

}  // namespace rehearse::ui
