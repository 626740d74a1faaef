#include "rehearse/ui/crashreport.hpp"

#include <QDateTime>
#include <QDir>
#include <QFile>
#include <QRegularExpression>
#include <QStandardPaths>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstring>

#include <execinfo.h>
#include <fcntl.h>
#include <unistd.h>

namespace rehearse::ui::crash {
namespace {

// Everything the handler reads is prepared before: it only calls open, write, backtrace_symbols_fd, close, signal
// and raise (async-signal-safe, backtrace warmed up at install so it does not load libgcc in the handler).
char reportPath[4096];
char header[1024];
char activity[256];
constexpr int kSignals[] = {SIGSEGV, SIGABRT, SIGFPE, SIGILL, SIGBUS};

void put(int fd, const char* text) {
  std::size_t n = std::strlen(text);
  while (n > 0) {
    const ssize_t w = ::write(fd, text, n);
    if (w <= 0) return;
    text += w;
    n -= static_cast<std::size_t>(w);
  }
}

const char* signalName(int sig) {
  switch (sig) {
    case SIGSEGV:
      return "SIGSEGV (invalid memory access)";
    case SIGABRT:
      return "SIGABRT (aborted)";
    case SIGFPE:
      return "SIGFPE (arithmetic error)";
    case SIGILL:
      return "SIGILL (illegal instruction)";
    case SIGBUS:
      return "SIGBUS (bus error)";
    default:
      return "a fatal signal";
  }
}

void onCrash(int sig) {
  const int fd = ::open(reportPath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
  if (fd >= 0) {
    put(fd, header);
    put(fd, "signal: ");
    put(fd, signalName(sig));
    put(fd, "\nwhat was running: ");
    put(fd, activity[0] ? activity : "(starting)");
    put(fd, "\nstack (innermost first):\n");
    void* frames[64];
    const int n = ::backtrace(frames, 64);
    ::backtrace_symbols_fd(frames, n, fd);
    ::close(fd);
  }
  // End as the signal would have (a core dump where the system keeps them).
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

}  // namespace

QString defaultFolder() {
  return QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + QStringLiteral("/crash-reports");
}

void install(const QString& folder, const QString& version) {
  QDir().mkpath(folder);
  const QString path =
      QDir(folder).filePath(QStringLiteral("crash-%1-%2.txt")
                                .arg(QDateTime::currentDateTime().toString(QStringLiteral("yyyyMMdd-HHmmss")))
                                .arg(static_cast<long long>(::getpid())));
  const QByteArray p = QFile::encodeName(path);
  std::memset(reportPath, 0, sizeof reportPath);
  std::memcpy(reportPath, p.constData(),
              std::min<std::size_t>(static_cast<std::size_t>(p.size()), sizeof reportPath - 1));
  const QByteArray h = QStringLiteral(
                           "Rehearse crash report (kept on this machine; never sent anywhere)\n"
                           "version: %1\nstarted: %2\nprocess: %3\n")
                           .arg(version, QDateTime::currentDateTime().toString(Qt::ISODate))
                           .arg(static_cast<long long>(::getpid()))
                           .toUtf8();
  std::memset(header, 0, sizeof header);
  std::memcpy(header, h.constData(), std::min<std::size_t>(static_cast<std::size_t>(h.size()), sizeof header - 1));
  void* warm[4];
  ::backtrace(warm, 4);  // loads what backtrace needs now, not in the handler
  struct sigaction action {};
  action.sa_handler = onCrash;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND | SA_NODEFER;
  for (int sig : kSignals) ::sigaction(sig, &action, nullptr);
}

void setActivity(const QString& what) {
  // The handler may read the buffer at any moment: end it first, write the text behind the end, then move the end.
  const QByteArray text = what.toUtf8().left(static_cast<int>(sizeof activity) - 1);
  activity[0] = 0;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  if (text.isEmpty()) return;
  std::memcpy(activity + 1, text.constData() + 1, static_cast<std::size_t>(text.size() - 1));
  activity[text.size()] = 0;
  std::atomic_signal_fence(std::memory_order_seq_cst);  // the text is in place before the handler can see it
  activity[0] = text[0];
}

QStringList pendingReports(const QString& folder) {
  QStringList out;
  const QDir dir(folder);
  for (const QString& f : dir.entryList({QStringLiteral("crash-*.txt")}, QDir::Files, QDir::Name))
    if (!f.endsWith(QStringLiteral(".shown.txt"))) out << dir.filePath(f);
  return out;
}

void markShown(const QString& report) {
  QString shown = report;
  shown.replace(QRegularExpression(QStringLiteral("\\.txt$")), QStringLiteral(".shown.txt"));
  QFile::remove(shown);
  QFile::rename(report, shown);
}

}  // namespace rehearse::ui::crash
