// The recording suite's test class (one executable, its slots run in this order): the slots are defined in
// test_recording.cpp (recording, verifying, replaying, metrics) and test_recording_sessions.cpp (checkpoints,
// settings, exports and the sessions' identity).
#pragma once

#include <QObject>
#include <QtTest>

class TestRecording : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase();
  void recordingFromBeforeTheMoveVerifies();
  void aSessionVerifiesUnderEveryKernel();
  void aSessionRecordedUnderThisKernelVerifiesElsewhere();
  void aReplayThatDiffersNamesTheKernels();
  void recordAndVerify();
  void clipsStopTheBleedingInARecordedSession();
  void metricsMatchTheScriptAndTheLiveRun();
  void aReplayReportsItsProgressAndStops();
  void seekingLandsOnTheStraightRun();
  void jawsKeepTheirHoldWhileTheBladeCuts();
  void aSlipTakenAgainReplays();
  void checkpointWithACutUnderWayIsComplete();
  void stabilitySettingsAreRecorded();
  void strainMatchesClosedForms();
  void exportsAndMetricsFromTheScript();
  void resetEndsTheRecordedSession();
  void aSessionWithoutStepsIsNotKept();
  void sessionsKeepTheirIdentityAcrossFiles();
};
