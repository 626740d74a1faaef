#pragma once
// Runs the `rehearse` command line as a user would (a child process), for the suites that test it.
#include <QProcess>
#include <QString>
#include <QStringList>

namespace testing {

struct Run {
  int code;  ///< exit code; -1 when it crashed or did not finish
  QString out, err;
};

inline Run run(const QStringList& args, int timeoutMs = 300000, const QProcessEnvironment* env = nullptr) {
  QProcess p;
  if (env) p.setProcessEnvironment(*env);
  p.start(QStringLiteral(REHEARSE_BINARY), args);
  p.waitForFinished(timeoutMs);
  return {p.exitStatus() == QProcess::NormalExit ? p.exitCode() : -1, QString::fromUtf8(p.readAllStandardOutput()),
          QString::fromUtf8(p.readAllStandardError())};
}

}  // namespace testing
