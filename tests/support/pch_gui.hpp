// Precompiled once and reused by every suite that drives the main window (tests/CMakeLists.txt, REUSE_FROM): Qt
// Widgets and Test, OpenCV's core, the main window's own header and what the core suites' header holds.
#pragma once
#include "pch_core.hpp"
#include <QtGui>
#include <QtWidgets>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"
