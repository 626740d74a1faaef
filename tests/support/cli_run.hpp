#pragma once
// Runs the `rehearse` command line as a user would (a child process), for the suites that test it.
#include <QProcess>
#include <QString>
#include <QStringList>
#include <QTest>

#include <sys/resource.h>

namespace testing {

struct Run {
  int code;  ///< exit code; -1 when it crashed or did not finish
  QString out, err;
};

/// The most memory a hostile file may make the program take (issue 60): 8 GiB of data (heap, anonymous mappings and
/// stacks; RLIMIT_DATA counts what is written, not address space reserved), applied in the child before it starts.
inline constexpr rlim_t kHostileMemoryLimit = rlim_t{8} << 30;
inline void limitChildMemory() {
  const rlimit limit{kHostileMemoryLimit, kHostileMemoryLimit};
  ::setrlimit(RLIMIT_DATA, &limit);
}

/// Runs the command line; with `boundMemory`, under kHostileMemoryLimit (past it, allocation fails in the child).
inline Run run(const QStringList& args, int timeoutMs = 300000, const QProcessEnvironment* env = nullptr,
               bool boundMemory = false) {
  QProcess p;
  if (env) p.setProcessEnvironment(*env);
  if (boundMemory) p.setChildProcessModifier(limitChildMemory);
  p.start(QStringLiteral(REHEARSE_BINARY), args);
  p.waitForFinished(timeoutMs);
  return {p.exitStatus() == QProcess::NormalExit ? p.exitCode() : -1, QString::fromUtf8(p.readAllStandardOutput()),
          QString::fromUtf8(p.readAllStandardError())};
}

/// A `simulate` or `gesture` run that took every step: no step failed, and the exit code is the one its printed
/// "statuses:" line calls for (0 when every step converged, 5 when some ended inexact or with inverted elements).
inline bool tookEveryStep(const Run& r) {
  const int i = r.out.indexOf(QLatin1String("statuses: "));
  if (i < 0) return false;
  // The counts only ("statuses: 298 converged, 2 inexact; largest relative residual ..., at most 0 inverted
  // elements, ..."): what follows the ';' names inverted elements whether there were any or not.
  QString line = r.out.mid(i, r.out.indexOf('\n', i) - i);
  line = line.left(line.indexOf(';'));
  const bool loose = line.contains(QLatin1String(" inexact")) || line.contains(QLatin1String(" inverted"));
  const bool failed = line.contains(QLatin1String(" failed")) || line.contains(QLatin1String(" refused"));
  return !failed && r.code == (loose ? 5 : 0);
}

/// A refusal as the command line gives it: the exit code, one line on stderr, and a fragment of its sentence.
inline void expectOneLineError(const Run& r, int code, const char* fragment) {
  QVERIFY2(r.code == code, qPrintable(QString("exit %1, stderr: %2").arg(r.code).arg(r.err)));
  QCOMPARE(r.err.trimmed().count('\n'), 0);
  QVERIFY2(r.err.contains(QLatin1String(fragment)), qPrintable(r.err));
}

}  // namespace testing
