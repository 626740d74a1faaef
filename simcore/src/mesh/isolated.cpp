// A child process for work a crash must not escape (see isolated.hpp).
#include <rehearse/simcore/isolated.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>

namespace rehearse::simcore {
namespace {

constexpr char kDone = 'D', kThrew = 'T';

void writeAll(int fd, const std::string& s) {
  std::size_t at = 0;
  while (at < s.size()) {
    const ssize_t n = ::write(fd, s.data() + at, s.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // the parent is gone: nothing to tell
    at += static_cast<std::size_t>(n);
  }
}

IsolatedResult inProcess(const std::function<std::string()>& work) {
  IsolatedResult r;
  try {
    r.bytes = work();
    r.status = IsolatedResult::Status::Done;
  } catch (const std::exception& e) {
    r.status = IsolatedResult::Status::Threw;
    r.message = e.what();
  }
  return r;
}

}  // namespace

IsolatedResult runIsolated(const std::function<std::string()>& work, double timeoutSeconds) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return inProcess(work);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return inProcess(work);
  }
  if (pid == 0) {
    ::close(fds[0]);
    // The parent's crash handler (ui/crashreport.cpp) would write a report in the parent's name: a crash here is the
    // file's, said by the parent, and the child just ends.
    for (int sig : {SIGSEGV, SIGABRT, SIGFPE, SIGILL, SIGBUS}) ::signal(sig, SIG_DFL);
    std::string out;
    try {
      out = kDone + work();
    } catch (const std::exception& e) {
      out = std::string(1, kThrew) + e.what();
    } catch (...) {
      out = std::string(1, kThrew) + "an unknown error";
    }
    writeAll(fds[1], out);
    ::_exit(0);
  }
  ::close(fds[1]);
  IsolatedResult r;
  std::string got;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeoutSeconds);
  bool timedOut = false;
  char buf[65536];
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timedOut = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<long long>(left.count(), 1000)));
    if (ready < 0 && errno != EINTR) break;
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // the child closed its end: done or dead
    got.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  if (timedOut) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timedOut) {
    r.status = IsolatedResult::Status::TimedOut;
    r.message = "did not finish within " + std::to_string(static_cast<int>(timeoutSeconds)) + " s";
    return r;
  }
  if (WIFSIGNALED(status)) {
    r.status = IsolatedResult::Status::Crashed;
    const char* name = ::strsignal(WTERMSIG(status));
    r.message = std::string("crashed (") + (name ? name : "signal " + std::to_string(WTERMSIG(status))) + ")";
    return r;
  }
  if (got.empty() || (got[0] != kDone && got[0] != kThrew) || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    r.status = IsolatedResult::Status::Crashed;
    r.message = "stopped without a result (exit code " +
                std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")";
    return r;
  }
  r.status = got[0] == kDone ? IsolatedResult::Status::Done : IsolatedResult::Status::Threw;
  (r.status == IsolatedResult::Status::Done ? r.bytes : r.message) = got.substr(1);
  return r;
}

}  // namespace rehearse::simcore
