#include <rehearse/simcore/session/background.hpp>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>

#if defined(__linux__)
#include <dirent.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace rehearse::simcore {

namespace {
std::atomic<int> wanted{0};
std::mutex foregroundMutex;
std::set<long> foreground;  // thread ids kept as they are

#if defined(__linux__)
long threadId() { return ::syscall(SYS_gettid); }

// Threads that only pass the window its input (the X connection's reader, D-Bus, GLib's): kept as they are, by name.
bool passesInput(long tid) {
  char path[64];
  std::snprintf(path, sizeof path, "/proc/self/task/%ld/comm", tid);
  std::FILE* f = std::fopen(path, "r");
  if (!f) return false;
  char name[32] = {};
  const bool read = std::fgets(name, sizeof name, f) != nullptr;
  std::fclose(f);
  if (!read) return false;
  for (const char* prefix : {"QXcb", "QDBus", "gdbus", "gmain", "dconf"})
    if (std::strncmp(name, prefix, std::strlen(prefix)) == 0) return true;
  return false;
}

// Raises thread `tid`'s nice value to `nice` if it is below; true if it did.
bool lower(long tid, int nice) {
  errno = 0;
  const int now = ::getpriority(PRIO_PROCESS, static_cast<id_t>(tid));
  return errno == 0 && now < nice && ::setpriority(PRIO_PROCESS, static_cast<id_t>(tid), nice) == 0;
}
#endif
}  // namespace

void setBackgroundNice(int nice) { wanted.store(nice); }

int backgroundNice() { return wanted.load(); }

void workInBackground() {
  const int nice = wanted.load();
  thread_local int applied = 0;
  if (nice <= 0 || applied >= nice) return;
  applied = nice;
#if defined(__linux__)
  lower(threadId(), nice);  // (PRIO_PROCESS with a thread id: on Linux the nice value is the thread's own)
#endif
}

void stayInForeground() {
#if defined(__linux__)
  std::lock_guard<std::mutex> lock(foregroundMutex);
  foreground.insert(threadId());
#endif
}

int sendOthersToBackground() {
  const int nice = wanted.load();
  int lowered = 0;
#if defined(__linux__)
  if (nice <= 0) return 0;
  std::set<long> keep;
  {
    std::lock_guard<std::mutex> lock(foregroundMutex);
    keep = foreground;
  }
  keep.insert(threadId());
  DIR* tasks = ::opendir("/proc/self/task");
  if (!tasks) return 0;
  while (const dirent* e = ::readdir(tasks)) {
    char* end = nullptr;
    const long tid = std::strtol(e->d_name, &end, 10);
    if (end == e->d_name || *end != '\0' || keep.count(tid) || passesInput(tid)) continue;
    lowered += lower(tid, nice);
  }
  ::closedir(tasks);
#endif
  return lowered;
}

}  // namespace rehearse::simcore
