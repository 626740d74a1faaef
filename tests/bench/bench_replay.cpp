// Benchmark of seeking in a recorded rehearsal (issue 16; not a test): a scripted grasp, pull and cut
// (resources/gestures/grasp-pull-cut.json, the linearised method with the asynchronous refresh the GUI uses)
// is recorded with its checkpoints on the built-in liver preset (3,760 tets) and on real organ shapes
// (SOFA's liver, the kidney and the uterus presets from ../shared/data, where present); then a replayer seeks
// to random steps in random order (backwards too). Reported per organ: the steps, the checkpoints, the
// time of a restore alone (seeking to a checkpoint's step from elsewhere), of a replayed step, and of the
// seeks (median, largest), each checked against the straight replay's checksum (a wrong seek is an error).
// Writes replay-seek.csv into the directory given (default ".").
//   bench_replay [OUT_DIR] [--quick]
#include "bench_args.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/app/recording.hpp>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace rehearse;

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  const auto [out, quick] = testing::benchArgs(argc, argv);

  const std::string shared = REHEARSE_SHARED_DATA;
  const app::GestureScript script = testing::gestureScript("grasp-pull-cut.json");
  std::ofstream csv(out + "/replay-seek.csv");
  csv << "organ,elements,steps,checkpoints,restore_median_ms,step_median_ms,seeks,seek_median_ms,seek_max_ms,seeks_over_200ms,wrong_seeks\n";
  int wrong = 0;
  std::vector<std::string> organs{"liver"};
  if (!quick)
    for (const char* o : {"sofa-liver", "kidney", "uterus"}) organs.push_back(o);
  for (const auto& organ : organs) {
    simcore::BodySetup setup;
    try {
      setup = testing::presetBody(organ, shared);
    } catch (const std::exception& e) {
      // A preset that cannot be built is a failure of the benchmark (its data is installed beside the project), not a row to leave out.
      std::fprintf(stderr, "bench_replay: the %s preset cannot be built: %s\n", organ.c_str(), e.what());
      return 1;
    }
    setup.settings.method = simcore::NewtonMethod::Linearised;
    setup.settings.factorRefresh = simcore::FactorRefresh::Asynchronous;
    const std::string file = out + "/replay-" + organ + ".rehearse";
    std::filesystem::remove(file);
    std::unique_ptr<app::Recorder> recorder;
    app::GestureHooks hooks;
    hooks.start = [&](const simcore::BodySetup& s) {
      recorder = std::make_unique<app::Recorder>(file, app::SessionMeta{"bench", organ, "", "", "", ""}, s);
    };
    hooks.step = [&](const simcore::StepRecord& r) { recorder->afterStep(r); };
    const app::GestureResult g = app::runGesture(setup, script, hooks);
    recorder->finish(static_cast<long>(g.steps.size()));
    recorder.reset();
    const app::Recording rec = app::loadRecording(file, 1);
    std::vector<std::uint64_t> straight{0};
    std::vector<double> stepMs;
    {
      app::Replayer r(rec);
      while (r.step() < r.steps()) {
        const auto t0 = std::chrono::steady_clock::now();
        r.advance();
        stepMs.push_back(msSince(t0));
        straight.push_back(app::stateChecksum(r.state()));
      }
    }
    app::Replayer replayer(rec);
    std::vector<double> restoreMs;
    for (long c : rec.checkpointSteps) {
      replayer.seek(c > 1 ? c - 1 : rec.summary.steps);  // elsewhere: the next seek restores c
      replayer.seek(rec.summary.steps);
      const auto t0 = std::chrono::steady_clock::now();
      replayer.seek(c);
      restoreMs.push_back(msSince(t0));
    }
    std::mt19937 rng(7);
    std::uniform_int_distribution<long> at(1, rec.summary.steps);
    std::vector<double> seekMs;
    const int seeks = quick ? 10 : 30;
    int over = 0;
    for (int k = 0; k < seeks; ++k) {
      const long target = at(rng);
      const auto t0 = std::chrono::steady_clock::now();
      replayer.seek(target);
      seekMs.push_back(msSince(t0));
      over += seekMs.back() > 200;
      if (std::getenv("BENCH_REPLAY_DETAIL")) {  // where the time of a slow seek goes: the restore, then each step again
        long from = std::max(0L, replayer.lastSeekFrom());
        const auto t1 = std::chrono::steady_clock::now();
        replayer.seek(rec.summary.steps);
        replayer.seek(from);
        std::string detail = std::to_string(msSince(t1)) + " ms restore;";
        while (replayer.step() < target) {
          const auto t2 = std::chrono::steady_clock::now();
          replayer.advance();
          if (msSince(t2) > 5) detail += " step " + std::to_string(replayer.step()) + ": " + std::to_string(msSince(t2)) + " ms;";
        }
        std::printf("  seek to %ld from %ld: %.1f ms (%s)\n", target, replayer.lastSeekFrom(), seekMs.back(), detail.c_str());
      }
      if (app::stateChecksum(replayer.state()) != straight[static_cast<std::size_t>(target)]) {
        ++wrong;
        std::fprintf(stderr, "%s: seeking to step %ld differs from the straight replay\n", organ.c_str(), target);
      }
    }
    const double seekMax = *std::max_element(seekMs.begin(), seekMs.end());
    std::printf("%s: %zu elements, %ld steps, %zu checkpoints; restore %.1f ms, replayed step %.2f ms (medians); %d seeks: median %.1f ms, largest %.1f ms, "
                "%d over 200 ms\n",
                organ.c_str(), setup.mesh.tets.size(), rec.summary.steps, rec.checkpointSteps.size(), median(restoreMs), median(stepMs), seeks, median(seekMs),
                seekMax, over);
    csv << organ << ',' << setup.mesh.tets.size() << ',' << rec.summary.steps << ',' << rec.checkpointSteps.size() << ',' << median(restoreMs) << ','
        << median(stepMs) << ',' << seeks << ',' << median(seekMs) << ',' << seekMax << ',' << over << ',' << wrong << '\n';
    std::filesystem::remove(file);
  }
  if (wrong) {
    std::fprintf(stderr, "bench_replay: %d seeks landed on another state\n", wrong);
    return 1;
  }
  return 0;
}
