#pragma once
// A latest-value cell that one thread writes and any thread reads without a lock (a sequence lock over
// relaxed atomics, Boehm 2012's pattern): the 1 kHz tool-force loop reads what the physics step and the
// GUI publish without ever waiting on a thread of lower priority (a mutex held by a preempted GUI or
// stepping thread would stall it: priority inversion).
#include <array>
#include <atomic>
#include <cstddef>

namespace rehearse::simcore {

template <std::size_t N>
class SeqCell {
 public:
  /// One writer at a time.
  void store(const std::array<double, N>& v) {
    const unsigned s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < N; ++i) v_[i].store(v[i], std::memory_order_relaxed);
    seq_.store(s + 2, std::memory_order_release);
  }
  /// Any thread; retries while a store is under way (a few nanoseconds).
  std::array<double, N> load() const {
    std::array<double, N> out{};
    for (;;) {
      const unsigned s1 = seq_.load(std::memory_order_acquire);
      if (s1 & 1u) continue;
      for (std::size_t i = 0; i < N; ++i) out[i] = v_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s1) return out;
    }
  }

 private:
  std::atomic<unsigned> seq_{0};
  std::array<std::atomic<double>, N> v_{};
};

}  // namespace rehearse::simcore
