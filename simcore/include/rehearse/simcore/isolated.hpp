#pragma once
// Work on a user's file by a library we cannot mend (assimp 5.2 from Debian, not built with checks; its readers have
// known memory errors on damaged files) runs in a child process, so that a crash there is a refusal of the file and
// never takes the application, and the surgeon's work in it, down.
#include <functional>
#include <string>

namespace rehearse::simcore {

/// What `runIsolated` brought back: the child's bytes, or why there are none.
struct IsolatedResult {
  enum class Status {
    Done,      ///< `work` returned; `bytes` is what it returned
    Threw,     ///< `work` threw; `message` is the exception's what()
    Crashed,   ///< the child ended by a signal or without a result; `message` says which
    TimedOut,  ///< the child ran past the time allowed and was stopped
  };
  Status status = Status::Crashed;
  std::string bytes;
  /// Threw: the exception's sentence. Crashed, TimedOut: what the child did, to follow "the reader" ("crashed
  /// (Segmentation fault)", "did not finish within 300 s").
  std::string message;
};

/// Runs `work` in a forked child and returns its bytes through a pipe. The child only runs `work` and leaves with
/// _exit (no atexit handlers, no Qt): `work` must not touch other threads' state. A child still running after
/// `timeoutSeconds` is killed. When no child can be started (fork fails), `work` runs here.
IsolatedResult runIsolated(const std::function<std::string()>& work, double timeoutSeconds);

}  // namespace rehearse::simcore
