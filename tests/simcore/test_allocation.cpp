// The time step reuses its scratch memory: after a warm-up, a step of the lagged methods allocates
// nothing on the heap. malloc and friends are interposed in this executable (they forward to glibc) and
// counted while a flag is set, so allocations by Eigen, CHOLMOD, TBB and the standard library all count.
#include "test_support.hpp"

#include "phantom/phantom.hpp"

#include <rehearse/simcore/integrator.hpp>

#include <atomic>
#include <cstdlib>

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);
}

namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
inline void count() {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(size_t a, size_t b) {
  count();
  return __libc_calloc(a, b);
}
void* realloc(void* p, size_t n) {
  count();
  return __libc_realloc(p, n);
}
void free(void* p) { __libc_free(p); }
void* memalign(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* aligned_alloc(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, size_t a, size_t n) {
  count();
  *out = __libc_memalign(a, n);
  return *out ? 0 : 12;
}
}

using namespace rehearse::simcore;

class TestAllocation : public QObject {
  Q_OBJECT
 private slots:
  void interpositionWorks() {
    counting = true;
    allocations = 0;
    void* volatile p = std::malloc(64);
    std::vector<double>* volatile v = new std::vector<double>(100);
    counting = false;
    delete v;
    std::free(p);
    QVERIFY(allocations >= 2);  // the counter sees both malloc and operator new
  }

  void stepsDoNotAllocate() {
    const auto c = rehearse::phantom::makePhantom();
    const FemModel m = FemModel::build(c.volume, {{2, {MaterialModel::Corotational, 620e3, 0.45, 1100}}},
                                       {MaterialModel::Corotational, 27e3, 0.40, 1000});
    struct Variant {
      NewtonMethod method;
      bool simplicial;
      AttachmentMode attachments = AttachmentMode::Projection;
      // Steps ended at 0.05 mm with every estimate checked on the tangent, Newton's second correction too (as after a
      // cut or a tear: Integrator::setVerifyEveryEstimate).
      bool verified = false;
    };
    const Variant variants[] = {{NewtonMethod::Exact, false},
                                {NewtonMethod::LaggedPcg, false},
                                {NewtonMethod::Chord, false},
                                {NewtonMethod::Linearised, false},
                                {NewtonMethod::NewtonKrylov, false},
                                {NewtonMethod::Exact, true},
                                {NewtonMethod::Linearised, true},
                                // Attachments by Lagrange multipliers: the Schur complement and its solves too.
                                {NewtonMethod::LaggedPcg, false, AttachmentMode::Lagrange},
                                {NewtonMethod::NewtonKrylov, false, AttachmentMode::Lagrange},
                                {NewtonMethod::Exact, true, AttachmentMode::Lagrange},
                                {NewtonMethod::Chord, false, AttachmentMode::Projection, true},
                                {NewtonMethod::Chord, true, AttachmentMode::Lagrange, true}};
    for (const auto& [method, simplicial, attachments, verified] : variants) {
      SimulationSettings s;
      s.method = method;
      s.simplicialFactor = simplicial;
      s.attachments = attachments;
      if (verified) s.accuracyPosition = 5e-5;
      Integrator in(m, c.attachments, s);
      in.setVerifyEveryEstimate(verified);
      auto state = in.initialState();
      for (int i = 0; i < 30; ++i) in.step(state);  // warm-up: buffers sized, the factor built
      long worst = 0, total = 0, refreshing = 0, quiet = 0, factorising = 0;
      for (int i = 0; i < 20; ++i) {
        allocations = 0;
        counting = true;
        const StepReport rep = in.step(state);
        counting = false;
        QVERIFY(rep.ok);
        total += allocations;
        worst = std::max(worst, allocations.load());
        if (rep.factorisations > 0) {
          refreshing += allocations;
          ++factorising;
        } else
          quiet = std::max(quiet, allocations.load());
      }
      qInfo(
          "%-11s %-10s %-10s %-8s heap allocations per step: %ld in total over 20 steps, at most %ld in one; %ld in steps "
          "that re-factorised, "
          "at most %ld in one that did not (%ld of 20 steps re-factorised)",
          toString(method).c_str(), simplicial ? "simplicial" : "supernodal",
          attachments == AttachmentMode::Lagrange ? "lagrange" : "projection", verified ? "verified" : "", total, worst, refreshing, quiet,
          factorising);
      // A step that reuses the factorisation allocates nothing. A supernodal numeric factorisation does,
      // inside CHOLMOD (its permuted transpose, and an OpenMP team per supernode from libgomp), reported
      // above; the simplicial factor of the matrix we permute ourselves allocates nothing at all.
      QCOMPARE(quiet, 0L);
      if (simplicial) QCOMPARE(total, 0L);
      if (method == NewtonMethod::Exact) QCOMPARE(factorising, 20L);
    }
  }
};

QTEST_GUILESS_MAIN(TestAllocation)
#include "test_allocation.moc"
