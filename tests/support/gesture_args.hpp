#pragma once
// The recording suites' gesture runs: a script from resources/gestures, and the command line that records it on the
// liver preset the way the GUI runs (linearised, asynchronous refresh).
#include <QString>
#include <QStringList>

namespace {
inline QString script(const char* name) { return QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/" + name; }
inline QStringList gestureArgs(const QString& dir, const char* scriptName, const QString& file) {
  return {"gesture",        "--preset",   "liver",     "--script",  script(scriptName),
          "--method",       "linearised", "--refresh", "async",     "--out",
          dir + "/out.vtu", "--record",   file,        "--trainee", "A. Trainee"};
}
}  // namespace
