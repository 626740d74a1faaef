#include "rehearse/ui/liveoverlay.hpp"

#include "rehearse/ui/frameview.hpp"
#include "simulatedcase.hpp"

#include <QFutureWatcher>
#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

namespace {
constexpr qint64 kLiveOverlayMs = 16;  // at most 60 drawings a second
}  // namespace

LiveOverlay::LiveOverlay(FrameView* view, QObject* parent) : QObject(parent), view_(view) {
  timer_.setSingleShot(true);
  timer_.setInterval(static_cast<int>(kLiveOverlayMs));
  connect(&timer_, &QTimer::timeout, this, &LiveOverlay::drawIfDue);
}

void LiveOverlay::request(Job job) {
  pending_ = std::move(job);
  drawIfDue();
}

bool LiveOverlay::due() const {
  // Not before the last drawing reached the screen.
  return !clock_.isValid() || (clock_.elapsed() >= kLiveOverlayMs && view_->paints() != paints_);
}

void LiveOverlay::drawIfDue() {
  if (!pending_ || busy_) return;
  if (!due()) {
    if (!timer_.isActive()) timer_.start();  // the last frame is drawn even when the simulation stops
    return;
  }
  Job job = std::move(*pending_);
  pending_.reset();
  busy_ = true;
  clock_.start();
  paints_ = view_->paints();
  auto* watcher = new QFutureWatcher<OverlayPicture>(this);
  connect(watcher, &QFutureWatcher<OverlayPicture>::finished, this, [this, watcher, organ = job.c->organ] {
    watcher->deleteLater();
    busy_ = false;
    emit drawn(watcher->result(), organ);
    drawIfDue();
  });
  watcher->setFuture(QtConcurrent::run([overlay = overlay_, job = std::move(job)] {
    if (job.surface)
      return overlay->renderLive(*job.c, job.positions, *job.surface, job.tets, job.labels, job.inner);
    // Uncut: the case with the simulated nodes as its shape (as an elastic fit's), drawn as the case is.
    return overlay->render(simulatedCase(*job.c, job.positions), job.inner);
  }));
}

}  // namespace rehearse::ui
