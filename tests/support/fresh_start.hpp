#pragma once
// A GUI suite's run starts as a first start on a fresh machine (see forgetEarlierRuns).
#include <QDir>
#include <QMessageBox>
#include <QPushButton>
#include <QSettings>
#include <QStandardPaths>
#include <QTest>
#include <QWidget>

namespace {
// Every run of a GUI suite is a first start, as on a fresh machine (CI's): the settings (window layout, recent files,
// remembered choices) and the application data (autosave, crash reports) an earlier run of this test program left in
// its test location are removed, once per run, before its first window. (Kept, a second run differed from the first:
// a saved window layout once hid a first start's squeezed frame view.) Call after setOrganizationName.
inline void forgetEarlierRuns() {
  static bool forgotten = false;
  if (forgotten) return;
  forgotten = true;
  QStandardPaths::setTestModeEnabled(true);  // never the user's own settings
  QSettings settings;
  settings.clear();
  settings.sync();
  QDir(QStandardPaths::writableLocation(QStandardPaths::AppDataLocation)).removeRecursively();
}

// Closes a main window as a person who does not keep its unsaved changes: Discard in the box that asks (issue 62), if
// it asks (about the case's unsaved changes, or about a rehearsal nothing keeps). True when the window closed.
inline bool closeDiscardingChanges(QWidget& window) {
  window.close();
  for (const char* name : {"unsavedChangesBox", "unkeptRehearsalBox", "endRehearsalBox"})
    if (auto* box = window.findChild<QMessageBox*>(QString::fromLatin1(name)))
      QTest::mouseClick(box->button(QMessageBox::Discard), Qt::LeftButton);
  return !window.isVisible();
}
}  // namespace
