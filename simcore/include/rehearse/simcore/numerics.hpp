#pragma once
// The numerical kernels behind a step, named and pinned (issue 60: a recording is a fact about the rehearsal, not
// about the processor). CHOLMOD's supernodal factor and solves call BLAS and LAPACK; OpenBLAS picks its kernels by
// processor (and by OPENBLAS_CORETYPE), and their rounding differs. The program links OpenBLAS by its own name, ahead
// of whatever BLAS the machine's alternatives select, and pins it to one kernel set at start: the same bits on any
// x86-64 processor. The simplicial factor calls no BLAS at all. glibc's libm likewise picks FMA versions of its
// functions by processor: each process masks them at start (numerics.cpp), so libm too gives the same bits everywhere.
#include <string>

namespace rehearse::simcore {

/// The OpenBLAS kernel set every process of this program uses (one that runs on any x86-64 processor).
inline constexpr const char* kPinnedBlasCore = "Prescott";

/// Pins OpenBLAS to kPinnedBlasCore (once per process; runs before main, and again harmlessly from the solvers).
/// False when the BLAS that CHOLMOD calls is not a dynamic-architecture OpenBLAS (blasKernel() then says which).
bool pinBlasKernel();

/// For benchmarks and tests only: re-selects OpenBLAS's kernels for `core` (an OPENBLAS_CORETYPE name: Haswell,
/// SkylakeX, Zen...). Only while no other thread calls BLAS. False when there is no dynamic OpenBLAS, or the core
/// is unknown to it, or this processor lacks its instructions (AVX2 for Haswell and Zen, AVX-512 for SkylakeX and
/// Cooperlake). pinBlasKernel() restores the pinned one.
bool selectBlasCore(const std::string& core);

/// The kernel set OpenBLAS chose when the process started, before the pin (this processor's, or OPENBLAS_CORETYPE's).
std::string blasCoreChosenAtStart();

/// The BLAS kernel CHOLMOD's calls reach now, e.g. "OpenBLAS 0.3.21 Prescott", or the library's file when it is
/// not OpenBLAS ("BLAS of /usr/lib/x86_64-linux-gnu/blas/libblas.so.3").
std::string blasKernel();

/// glibc's libm as this process runs it: "glibc 2.36 libm without FMA" (the FMA and FMA4 versions masked at start, so
/// that exp, log, pow, sin, cos, atan2... give the same bits on every processor) or "... with this processor's FMA".
std::string libmKernel();

/// The numerical kernels of a step: "CHOLMOD supernodal, OpenBLAS 0.3.21 Prescott; glibc 2.36 libm without FMA", or
/// "CHOLMOD simplicial (no BLAS); ...".
std::string linearSolveKernel(bool simplicialFactor);

/// This build's compiler and the flags that decide its floating point ("g++ 12.2.0, x86-64 baseline, no FP
/// contraction"), for a recording's provenance.
std::string numericalBuild();

}  // namespace rehearse::simcore
