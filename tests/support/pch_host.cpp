// The object that carries the precompiled header the suites reuse (tests/CMakeLists.txt).
