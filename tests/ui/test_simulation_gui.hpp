// The simulation panel suite's test class (one executable, its slots run in this order): the slots are defined in
// test_simulation_gui.cpp (the simulation panel) and test_simulation_gui_fit.cpp (steps 5 and 2-3: the fits).
#pragma once

#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QElapsedTimer>
#include <QObject>
#include <QtTest>

#include <memory>

class TestSimulationGui : public QObject {
  Q_OBJECT
  std::unique_ptr<rehearse::ui::MainWindow> w_;
  rehearse::ui::SimulationPanel* panel_ = nullptr;

  // Waits until the panel shows a frame with more than `steps` steps.
  bool waitForSteps(long steps, int ms = 30000) {
    QElapsedTimer t;
    t.start();
    while (t.elapsed() < ms) {
      if (panel_->lastFrame() && panel_->lastFrame()->steps > steps) return true;
      QTest::qWait(10);
    }
    return false;
  }

 private slots:
  void initTestCase();
  void singleStepWithTheMouse();
  void playAndPauseWithTheKeyboard();
  void simulationViewShowsTheWholeOrgan();
  void liveEditAppliesAtTheNextStep();
  void accuracyIsAskedInMillimetres();
  void aStepThatDidNotConvergeShowsNoEarlierDistance();
  void vonMisesColouring();
  void resetReturnsToRest();
  void startWhereTheFrameShowsIt();
  void invertedElementsAreShownOnTheOrgan();
  void elasticFitStep();
  void anatomicalCurveStep();
  void guiFitUsesTheCaseMaterialAndMatchesTheCommandLine();
  void secondFrameInTheGui();
  void ambiguousFitOffersItsAlternatives();
  void aRefusedStartIsSaidUntilItsCauseGoes();
  void aFallingFragmentDoesNotSetTheColourBar();
  void cleanupTestCase();
};
