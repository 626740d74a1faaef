#pragma once
// What the main window's translation units share (mainwindow.cpp, mainwindow_docks.cpp, mainwindow_menus.cpp).
#include <QString>

namespace rehearse::ui {

/// "3  Contour": a workflow step's number and title, as the workflow panel and the Step menu show it.
QString stepName(int i);

/// The frame view's property set from Reset until the Reset's own frame (step 0) is shown: the frames of steps taken
/// before it, still on their way, are not drawn over the organ at rest (MainWindow::showSimulationFrame).
inline constexpr const char* kFramesBeforeReset = "rehearse.framesBeforeReset";

}  // namespace rehearse::ui
