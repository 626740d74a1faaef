#pragma once
// The 3D mouse (3Dconnexion SpaceMouse, SpaceNavigator and the like) through Debian's libspnav, which talks to the
// spacenavd daemon over its UNIX socket (SPNAV_SOCKET, else /etc/spnavrc's socket, else /var/run/spnav.sock): a
// simcore::MotionDevice of the rate kind (simcore/session/device.hpp). Only one connection per process (libspnav's).
//
// To use a real one: `apt-get install spacenavd` (it starts at boot and finds the device over USB), then in step 7
// Simulation > Connect 3D mouse (or `rehearse device` to see its readings).
#include <rehearse/simcore/session/device.hpp>

#include <memory>
#include <string>

namespace rehearse::app {

/// Full travel of a 3D mouse's axis as spacenavd reports it (its counts at the cap's stop; SpaceNavigator: ~350).
inline constexpr double kSpaceNavFullTravel = 350.0;

/// Connects to spacenavd: the device, or null with one sentence in `why` (no daemon: how to install it).
std::unique_ptr<simcore::MotionDevice> openSpaceNav(std::string& why);

/// One spacenavd motion's axes (counts) as a reading (each -1..1 of kSpaceNavFullTravel), keeping `buttons`.
simcore::DeviceReading spaceNavReading(const int axes[6], unsigned buttons);

}  // namespace rehearse::app
