// The 3D mouse through libspnav (app/spacenav.hpp).
#include "rehearse/app/spacenav.hpp"

#include <spnav.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>

namespace rehearse::app {
namespace {

std::atomic<bool> connected{false};  // libspnav keeps one connection per process

class SpaceNav final : public simcore::MotionDevice {
 public:
  ~SpaceNav() override {
    spnav_close();
    connected = false;
  }
  std::string name() const override {
    char buf[128] = {};
    return spnav_dev_name(buf, sizeof buf) > 0 ? std::string("3D mouse (") + buf + ")" : std::string("3D mouse");
  }
  bool read(simcore::DeviceReading& reading, std::string& error) override {
    bool any = false;
    spnav_event ev;
    int got;
    // Every event queued since the last read: the motion's latest axes, every button's change.
    while ((got = spnav_poll_event(&ev)) > 0) {
      if (ev.type == SPNAV_EVENT_MOTION) {
        const int axes[6] = {ev.motion.x, ev.motion.y, ev.motion.z, ev.motion.rx, ev.motion.ry, ev.motion.rz};
        last_ = spaceNavReading(axes, last_.buttons);
        any = true;
      } else if (ev.type == SPNAV_EVENT_BUTTON && ev.button.bnum >= 0 && ev.button.bnum < 32) {
        const unsigned bit = 1u << static_cast<unsigned>(ev.button.bnum);
        last_.buttons = ev.button.press ? (last_.buttons | bit) : (last_.buttons & ~bit);
        any = true;
      }
    }
    // libspnav reads an ended connection as "no event": a peek that reads 0 bytes says the daemon went away.
    char c;
    if (spnav_fd() < 0 || ::recv(spnav_fd(), &c, 1, MSG_PEEK | MSG_DONTWAIT) == 0) {
      error = "The 3D mouse's connection to spacenavd was lost (the daemon stopped).";
      return false;
    }
    if (any) reading = last_;
    return any;
  }

 private:
  simcore::DeviceReading last_;
};

}  // namespace

simcore::DeviceReading spaceNavReading(const int axes[6], unsigned buttons) {
  simcore::DeviceReading r;
  r.kind = simcore::DeviceReading::Kind::Rate;
  for (int a = 0; a < 3; ++a) {
    r.translation(a) = std::clamp(axes[a] / kSpaceNavFullTravel, -1.0, 1.0);
    r.rotation(a) = std::clamp(axes[3 + a] / kSpaceNavFullTravel, -1.0, 1.0);
  }
  r.buttons = buttons;
  return r;
}

std::unique_ptr<simcore::MotionDevice> openSpaceNav(std::string& why) {
  if (connected.exchange(true)) {
    why = "The 3D mouse is already connected.";
    return nullptr;
  }
  if (spnav_open() == -1) {
    connected = false;
    why =
        "No 3D mouse: the spacenavd daemon is not running (install it with 'apt-get install spacenavd'; it finds the "
        "device over USB).";
    return nullptr;
  }
  if (spnav_protocol() >= 1) spnav_client_name("Rehearse");  // (an old daemon would read it as a sensitivity)
  return std::make_unique<SpaceNav>();
}

}  // namespace rehearse::app
