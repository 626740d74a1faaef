#pragma once
// A stand-in for the spacenavd daemon (tests of the 3D mouse without hardware): listens on a UNIX socket, is named to
// libspnav through SPNAV_SOCKET, and speaks spacenavd's event protocol (v0: 8 int32 per event; motion 0, x y z rx ry
// rz, period; press 1 / release 2, button number). libspnav's protocol-change request is answered "protocol 0", as a
// daemon that speaks only v0 would (the library then reads events only).
#include <QTemporaryDir>
#include <QtGlobal>

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

namespace rehearse::testing {

class FakeSpacenavd {
 public:
  FakeSpacenavd() {
    path_ = dir_.filePath(QStringLiteral("spnav.sock")).toStdString();
    listen_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path_.c_str(), sizeof addr.sun_path - 1);
    ok_ = listen_ >= 0 && ::bind(listen_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
          ::listen(listen_, 4) == 0;
    ::setenv("SPNAV_SOCKET", path_.c_str(), 1);
    if (ok_) acceptor_ = std::thread([this] { accepted_ = acceptOne(); });
  }
  ~FakeSpacenavd() {
    if (acceptor_.joinable()) acceptor_.join();
    stop();
    if (listen_ >= 0) ::close(listen_);
    ::unsetenv("SPNAV_SOCKET");
  }
  bool listening() const { return ok_; }
  /// Whether a client connected (within 10 s of the daemon's start) and had its protocol request answered; the
  /// daemon accepts on its own thread, so the client may open before or after this call.
  bool accept() {
    if (acceptor_.joinable()) acceptor_.join();
    return accepted_;
  }
  bool motion(int x, int y, int z, int rx, int ry, int rz, int period = 16) {
    const std::int32_t e[8] = {0, x, y, z, rx, ry, rz, period};
    return send(e);
  }
  bool button(int number, bool press) {
    const std::int32_t e[8] = {press ? 1 : 2, number, 0, 0, 0, 0, 0, 0};
    return send(e);
  }
  /// The daemon stops: the client's connection ends.
  void stop() {
    if (client_ >= 0) ::close(client_);
    client_ = -1;
  }

 private:
  bool acceptOne() {
    pollfd p{listen_, POLLIN, 0};
    if (::poll(&p, 1, 10000) != 1) return false;
    client_ = ::accept(listen_, nullptr, nullptr);
    if (client_ < 0) return false;
    std::int32_t request = 0, protocol = 0;
    pollfd c{client_, POLLIN, 0};
    if (::poll(&c, 1, 2000) != 1 || ::read(client_, &request, sizeof request) != sizeof request) return false;
    return ::write(client_, &protocol, sizeof protocol) == sizeof protocol;
  }
  bool send(const std::int32_t (&e)[8]) {
    return client_ >= 0 && ::write(client_, e, sizeof e) == static_cast<ssize_t>(sizeof e);
  }
  QTemporaryDir dir_;
  std::string path_;
  int listen_ = -1, client_ = -1;
  bool ok_ = false;
  bool accepted_ = false;
  std::thread acceptor_;
};

}  // namespace rehearse::testing
