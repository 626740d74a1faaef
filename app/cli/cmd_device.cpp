// `rehearse device`: the 3D mouse as spacenavd reports it (to check one before a rehearsal; app/spacenav.hpp).
#include "support.hpp"

#include <rehearse/app/spacenav.hpp>

#include <chrono>
#include <cstdio>
#include <thread>

namespace rehearse::app::cli {
namespace {

int cmdDevice(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, deviceCommand());
  const double seconds = o.count("seconds") ? parseNumber(o["seconds"], "--seconds") : 10.0;
  if (!(seconds > 0 && seconds <= 3600)) throw UsageError("--seconds must be between 0 and 3600");
  std::string why;
  auto device = openSpaceNav(why);
  if (!device) {
    std::fprintf(stderr, "rehearse: %s\n", why.c_str());
    return 1;
  }
  std::printf("%s: push and turn the cap, press its buttons (%.1f s; readings are -1..1 of full travel)\n",
              device->name().c_str(), seconds);
  std::fflush(stdout);
  const auto start = std::chrono::steady_clock::now();
  long readings = 0;
  Eigen::Vector3d most = Eigen::Vector3d::Zero(), mostTurn = Eigen::Vector3d::Zero();
  simcore::DeviceReading r;
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < seconds) {
    std::string error;
    if (device->read(r, error)) {
      ++readings;
      most = most.cwiseMax(r.translation.cwiseAbs());
      mostTurn = mostTurn.cwiseMax(r.rotation.cwiseAbs());
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("%7.2f s  move %+.2f %+.2f %+.2f  turn %+.2f %+.2f %+.2f  buttons %u\n", t, r.translation.x(),
                  r.translation.y(), r.translation.z(), r.rotation.x(), r.rotation.y(), r.rotation.z(), r.buttons);
      std::fflush(stdout);
    } else if (!error.empty()) {
      std::fprintf(stderr, "rehearse: %s\n", error.c_str());
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::printf("%ld readings; the largest: move %.2f %.2f %.2f, turn %.2f %.2f %.2f\n", readings, most.x(), most.y(),
              most.z(), mostTurn.x(), mostTurn.y(), mostTurn.z());
  return 0;
}

}  // namespace

const Command& deviceCommand() {
  static const Command command{
      "device",
      "  rehearse device [--seconds S]    the 3D mouse's readings as spacenavd reports them, for S s (10 by "
      "default);\n"
      "                                   exit 1 with a sentence when no spacenavd runs\n",
      {{"seconds", "S", "how long to read the device (s)"}},
      cmdDevice};
  return command;
}

}  // namespace rehearse::app::cli
