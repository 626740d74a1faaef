// Precompiled once and reused by every suite that does not link the GUI (tests/CMakeLists.txt, REUSE_FROM): the
// headers nearly all of them include, whose parsing took most of each suite's compile time (Qt Core through QtTest,
// Eigen, the standard library). Nothing here is a test's own: a suite still includes what it uses.
#pragma once
#include <QtTest>
#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>
