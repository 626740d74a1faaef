#include <rehearse/simcore/numerics.hpp>

#include <Eigen/Core>
#include <cholmod.h>
#include <dlfcn.h>
#include <gnu/libc-version.h>
#include <strings.h>
#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>
#include <string>

extern "C" {
// OpenBLAS (every build); the dynamic-architecture entry points are looked up, since a build for one processor has
// none.
char* openblas_get_config(void);
char* openblas_get_corename(void);
}

namespace rehearse::simcore {
namespace {

// glibc's libm picks FMA (or FMA4) versions of exp, log, pow, sin, cos, atan2, acos, log1p and expm1 by processor, and
// they round differently from the SSE2 versions a processor without FMA runs (measured here: 9 of 13 functions give
// other bits over 2 million arguments with FMA masked). Eigen's eigen solvers and rotations call them. So a process
// whose glibc was not told to mask those features starts itself once more with GLIBC_TUNABLES masking them (read
// by the dynamic linker, before any function is bound): every processor then runs the same libm code. Programs it
// starts inherit the setting. REHEARSE_KEEP_LIBM=1 keeps the processor's own (numericalBuild() then says so).
constexpr const char* kLibmMask = "-AVX2,-FMA,-FMA4";

bool libmMasked() {
  const char* t = std::getenv("GLIBC_TUNABLES");
  return t && std::strstr(t, kLibmMask) != nullptr;
}

// The command line's sub-commands that neither record nor replay a rehearsal start without it (starting again costs
// about 0.3 s here: every library is loaded twice); the GUI, `replay`, `publish`, `gesture --record` and the test
// programs do.
bool neitherRecordsNorReplays(int argc, char** argv) {
  if (argc < 2 || !argv[1]) return false;
  const std::string command = argv[1];
  for (const char* c : {"info", "mesh", "phantom", "simulate", "register", "appearance", "compose", "device",
                        "--version", "--help", "-h", "help"})
    if (command == c) return true;
  if (command == "gesture") {
    for (int i = 2; i < argc; ++i)
      if (argv[i] && std::strcmp(argv[i], "--record") == 0) return false;
    return true;
  }
  return false;
}

[[gnu::constructor(101)]] void maskLibmAtStart(int argc, char** argv, char** /*envp*/) {
  const char* keep = std::getenv("REHEARSE_KEEP_LIBM");
  if (libmMasked() || (keep && *keep && std::strcmp(keep, "0") != 0) || std::getenv("REHEARSE_LIBM_RESTARTED") ||
      !argv || neitherRecordsNorReplays(argc, argv))
    return;
  const char* old = std::getenv("GLIBC_TUNABLES");
  std::string value = old ? old : "";
  const std::string key = "glibc.cpu.hwcaps=";
  if (const auto at = value.find(key); at != std::string::npos) {
    const auto end = value.find(':', at);
    const auto insertAt = end == std::string::npos ? value.size() : end;
    value.insert(insertAt, std::string(insertAt > at + key.size() ? "," : "") + kLibmMask);
  } else {
    value += (value.empty() ? "" : ":") + key + kLibmMask;
  }
  setenv("GLIBC_TUNABLES", value.c_str(), 1);
  setenv("REHEARSE_LIBM_RESTARTED", "1", 1);  // never a loop, whatever the dynamic linker does with the setting
  execv("/proc/self/exe", argv);
  // Not restarted (no /proc): the processor's own libm, said by numericalBuild().
  if (old) setenv("GLIBC_TUNABLES", old, 1);
  else unsetenv("GLIBC_TUNABLES");
}

std::mutex& blasMutex() {
  static std::mutex m;
  return m;
}

using VoidFn = void (*)();

// OpenBLAS's own start-up path, run again for another core: it reads OPENBLAS_CORETYPE (set for the call, then put
// back as it was) and sets the chosen kernels' blocking parameters.
bool reselect(const char* core) {
  auto quit = reinterpret_cast<VoidFn>(dlsym(RTLD_DEFAULT, "gotoblas_dynamic_quit"));
  auto init = reinterpret_cast<VoidFn>(dlsym(RTLD_DEFAULT, "gotoblas_dynamic_init"));
  if (!quit || !init) return false;
  const char* was = std::getenv("OPENBLAS_CORETYPE");
  const std::string saved = was ? was : "";
  setenv("OPENBLAS_CORETYPE", core, 1);
  quit();
  init();
  if (was)
    setenv("OPENBLAS_CORETYPE", saved.c_str(), 1);
  else
    unsetenv("OPENBLAS_CORETYPE");
  const char* now = openblas_get_corename();
  return now && strcasecmp(now, core) == 0;
}

// Where CHOLMOD's dgemm_ goes: the library that defines the symbol the dynamic linker bound first.
std::string blasLibrary() {
  Dl_info info{};
  void* sym = dlsym(RTLD_DEFAULT, "dgemm_");
  if (sym && dladdr(sym, &info) && info.dli_fname) return info.dli_fname;
  return "";
}

bool boundToOpenBlas() {
  void* ours = reinterpret_cast<void*>(&openblas_get_config);
  Dl_info a{}, b{};
  void* sym = dlsym(RTLD_DEFAULT, "dgemm_");
  return sym && dladdr(sym, &a) && dladdr(ours, &b) && a.dli_fbase == b.dli_fbase;
}

}  // namespace

namespace {
std::string& coreAtStart() {
  static std::string core;
  return core;
}
}  // namespace

std::string blasCoreChosenAtStart() { return coreAtStart(); }

bool pinBlasKernel() {
  std::lock_guard<std::mutex> lock(blasMutex());
  const char* now = openblas_get_corename();
  if (coreAtStart().empty() && now) coreAtStart() = now;
  if (now && strcasecmp(now, kPinnedBlasCore) == 0) return boundToOpenBlas();
  return reselect(kPinnedBlasCore) && boundToOpenBlas();
}

bool selectBlasCore(const std::string& core) {
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  const std::string c = [&] {
    std::string s = core;
    for (auto& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return s;
  }();
  if ((c == "haswell" || c == "zen") && !avx2) return false;
  if ((c == "skylakex" || c == "cooperlake") && !avx512) return false;
  std::lock_guard<std::mutex> lock(blasMutex());
  return reselect(core.c_str());
}

std::string blasKernel() {
  if (!boundToOpenBlas()) {
    const std::string lib = blasLibrary();
    return "BLAS of " + (lib.empty() ? std::string("an unknown library") : lib);
  }
  std::string version = "OpenBLAS";
  if (const char* config = openblas_get_config()) {
    std::istringstream words(config);
    std::string name, number;
    if (words >> name >> number) version = name + " " + number;
  }
  const char* core = openblas_get_corename();
  return version + " " + (core ? core : "unknown core");
}

std::string libmKernel() {
  return std::string("glibc ") + gnu_get_libc_version() + " libm " +
         (libmMasked() ? "without FMA" : "with this processor's FMA");
}

std::string linearSolveKernel(bool simplicialFactor) {
  return (simplicialFactor ? std::string("CHOLMOD simplicial (no BLAS)") : "CHOLMOD supernodal, " + blasKernel()) +
         "; " + libmKernel();
}

std::string numericalBuild() {
  std::ostringstream s;
#if defined(__clang__)
  s << "clang++ " << __clang_major__ << '.' << __clang_minor__ << '.' << __clang_patchlevel__;
#elif defined(__GNUC__)
  s << "g++ " << __GNUC__ << '.' << __GNUC_MINOR__ << '.' << __GNUC_PATCHLEVEL__;
#else
  s << "an unknown compiler";
#endif
#if defined(__x86_64__)
  s << ", x86-64";
#if defined(__AVX__) || defined(__FMA__)
  s << " with AVX/FMA";
#else
  s << " baseline";
#endif
#else
  s << ", not x86-64";
#endif
#if defined(__FAST_MATH__)
  s << ", fast math";
#endif
  s << ", Eigen " << EIGEN_WORLD_VERSION << '.' << EIGEN_MAJOR_VERSION << '.' << EIGEN_MINOR_VERSION << ", CHOLMOD "
    << CHOLMOD_MAIN_VERSION << '.' << CHOLMOD_SUB_VERSION << '.' << CHOLMOD_SUBSUB_VERSION;
  return s.str();
}

}  // namespace rehearse::simcore
