#pragma once
// The threads that work for a window (the simulation, its factorisations and rebuilt bodies, the composition, long
// jobs, and the libraries' own worker threads) run below the GUI thread's scheduling priority, so that on a machine
// with fewer cores than busy threads the window still answers at once (issue 64: on 2 cores the window paused 33-75 ms
// in the actions of step 7 on the patient liver, the GUI thread waiting for a core behind four workers; 17-30 ms with
// them at nice +6).
namespace rehearse::simcore {

/// The nice value (Linux) such threads take: 0 (the default, as on the command line and in the benchmarks) leaves them
/// as they are. The GUI sets it once at start, before its first worker runs.
void setBackgroundNice(int nice);
int backgroundNice();

/// Called where a thread (or a pooled task) starts working for the window: this thread takes the background nice value
/// if it is below it (the threads it starts inherit it). Once per thread; nothing where the platform has no per-thread
/// nice value, where the value is 0, or where the system refuses (the window is then only less responsive).
void workInBackground();

/// The calling thread keeps its priority through sendOthersToBackground (the force loop: its period is the haptic
/// device's).
void stayInForeground();

/// Every thread of this process but the caller, those that stay in the foreground and those that pass the window its
/// input (Qt's X connection reader, D-Bus, GLib's, by their names) takes the background nice value if below it: the
/// threads the libraries start (TBB's workers for OpenCV, BLAS's) inherit their creator's, often the GUI thread's. The
/// GUI calls it now and then; it returns how many threads it lowered (0 where the platform has no per-thread nice value
/// or the value is 0).
int sendOthersToBackground();

}  // namespace rehearse::simcore
