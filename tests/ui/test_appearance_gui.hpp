// The appearance suite's test class (one executable, its slots run in this order) and its helpers: the helpers and
// the first slots are defined in test_appearance_gui.cpp, the slots from clipCutAndCauterize on in
// test_appearance_gui_tools.cpp.
#pragma once

#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QList>
#include <QObject>
#include <QString>
#include <QVariant>
#include <QtTest>

#include <memory>

class TestAppearanceGui : public QObject {
  Q_OBJECT
  std::unique_ptr<rehearse::ui::MainWindow> w_;
  rehearse::ui::SimulationPanel* panel_ = nullptr;

  // Step 7 over the frame, the simulation from rest and playing: true once its first steps on the organ are in.
  bool rehearseFromRest();
  // True once the simulation has taken `n` more steps.
  bool stepsOn(int n);
  // What the session and the panel say (for a failure's message: CI once saw the session stop stepping here).
  QString said() const;

  // F10 on the window, and the page's answer.
  QList<QVariant> estimateWithF10();
  // Edits, an undo and an import that end an unrecorded rehearsal ask first (aNewCaseEndsTheRehearsal's part).
  void editsThatEndTheRehearsalAsk(const QString& unkept, const QString& folder);

 private slots:
  void initTestCase();
  void estimateWithTheKeyboard();
  void waitForIdleShowsTheNewestComposition();
  void aTextureOnlyEstimateIsNotReshaded();
  void compositedViewFollowsTheSimulation();
  void everyViewShowsTheSimulatedOrgan();
  void cutOrganIsComposited();
  void graspPullCut();
  void clipCutAndCauterize();
  void graspPullUntilItTears();
  void viewModesWithTheKeyboard();
  void movedOrganMakesItStale();
  void escCancels();
  void organBehindTheCameraIsRefused();
  void savedAndComposedAgainAfterReopening();
  void aNewCaseEndsTheRehearsal();
  void cleanupTestCase();
};
