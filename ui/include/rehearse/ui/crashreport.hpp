#pragma once
// Crash reports (issue 39): a crash (SIGSEGV, SIGABRT, SIGFPE, SIGILL, SIGBUS) writes a local report (the version and
// git revision, the signal, what the program was doing, the stack as glibc's backtrace gives it) into the
// application's data folder, then ends the process as the signal would have. The next start offers it (MainWindow),
// with the autosaved case; nothing is ever sent anywhere.
#include <QString>
#include <QStringList>

namespace rehearse::ui::crash {

/// The folder reports go to: AppDataLocation/crash-reports.
QString defaultFolder();

/// Installs the handlers; reports go to `folder` (created). The report's file is named when the program starts
/// (crash-YYYYMMDD-HHMMSS-PID.txt) and written only on a crash. `version` is kept for the report.
void install(const QString& folder, const QString& version);

/// What the program is doing now ("step 5 Elastic fit", "job: Fitting the organ to the contour"), for a report:
/// a sentence kept in a fixed buffer the handler reads (at most 255 bytes). GUI thread.
void setActivity(const QString& what);

/// Reports of earlier runs not yet shown (oldest first).
QStringList pendingReports(const QString& folder);

/// Marks a report as shown (renamed *.shown.txt; kept for whoever wants it).
void markShown(const QString& report);

}  // namespace rehearse::ui::crash
