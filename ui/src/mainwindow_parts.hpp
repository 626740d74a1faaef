#pragma once
// What the main window's translation units share (mainwindow.cpp, mainwindow_docks.cpp, mainwindow_menus.cpp).
#include <QString>

namespace rehearse::ui {

/// "3  Contour": a workflow step's number and title, as the workflow panel and the Step menu show it.
QString stepName(int i);

}  // namespace rehearse::ui
