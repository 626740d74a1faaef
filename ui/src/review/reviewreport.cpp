// The review's PDF report (issue 16): Qt's QPdfWriter on A4 — the session's facts, its metrics with the
// trainer's thresholds and verdicts, the force and strain over time with the events marked, and key frames.
#include "rehearse/ui/reviewreport.hpp"
#include "rehearse/ui/qtapplication.hpp"
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/app/incorrect_actions.hpp>

#include <QCoreApplication>
#include <QGuiApplication>
#include <QImage>
#include <QPageSize>
#include <QPainter>
#include <QPainterPath>
#include <QPdfWriter>
#include <QSaveFile>
#include <QBuffer>
#include <QDir>

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace rehearse::ui {

// The events' tick colours, the ones the plot's legend names.
// A vessel cut's and an incorrect action's ticks are longer than the others.
static bool longTick(const std::string& e) {
  const simcore::EventKind k = simcore::eventKind(e);
  return k == simcore::EventKind::VesselCut || k == simcore::EventKind::IncorrectAction;
}

QColor reviewEventColour(const std::string& e) {
  using K = simcore::EventKind;
  switch (simcore::eventKind(e)) {
    case K::Grasp: return QColor(40, 160, 40);               // green
    case K::Release: return QColor(40, 160, 160);            // teal
    case K::Slip: return QColor(230, 140, 0);                // orange
    case K::Cut: return QColor(120, 0, 160);                 // purple
    case K::VesselCut: return QColor(200, 0, 0);             // red
    case K::ForceOverThreshold: return QColor(90, 90, 90);   // grey
    case K::Clip: return QColor(120, 130, 150);              // steel
    case K::ClipMisplaced: return QColor(220, 180, 0);       // amber
    case K::Bleeding: return QColor(110, 0, 20);             // dark red
    case K::BleedingStopped: return QColor(230, 110, 150);   // pink
    case K::Burn: return QColor(200, 190, 150);              // ash
    case K::EnergyOnStructure: return QColor(255, 60, 200);  // magenta
    case K::Tear: return QColor(150, 90, 40);                // brown
    case K::IncorrectAction: return QColor(0, 200, 230);     // cyan
    default: return {};
  }
}
const char* const kReviewEventLegend =
    "ticks: grasp green, release teal, slip orange, cut purple, vessel cut red (longer), force over the threshold "
    "grey, "
    "clip steel, clip misplaced amber, bleeding dark red, bleeding stopped pink, burn ash, energy on a structure "
    "magenta, tear brown, incorrect action cyan (longer)";

namespace {

QImage toQImage(const cv::Mat3b& m) {
  return QImage(m.data, m.cols, m.rows, static_cast<qsizetype>(m.step), QImage::Format_BGR888).copy();
}

QColor eventColour(const std::string& e) { return reviewEventColour(e); }
const char* kEventLegend = kReviewEventLegend;

QString number(double v) {
  if (v == 0) return "0";
  const double a = std::abs(v);
  if (a >= 1e4 || a < 1e-3) return QString::number(v, 'g', 4);
  return QString::number(v, 'f', a >= 100 ? 1 : a >= 1 ? 3 : 4);
}

// A plot of one series over time, the events marked as ticks along the top.
void plot(QPainter& p, const QRectF& box, const QString& title, const QString& unit,
          const std::vector<app::TimelineSample>& tl, double (*value)(const app::TimelineSample&), double threshold) {
  p.save();
  // The title wraps (its legend is long): the plot starts below however many lines it takes.
  const QRectF titleBox =
      p.boundingRect(QRectF(box.left(), box.top(), box.width(), 400), Qt::AlignLeft | Qt::TextWordWrap, title);
  p.drawText(QRectF(box.left(), box.top(), box.width(), titleBox.height()), Qt::AlignLeft | Qt::TextWordWrap, title);
  const double top = titleBox.height() + 10;
  const QRectF area(box.left() + 150, box.top() + top, box.width() - 200, box.height() - top - 50);
  p.setPen(QPen(Qt::black, 2));
  p.drawRect(area);
  if (tl.empty()) {
    p.drawText(area, Qt::AlignCenter, "no samples");
    p.restore();
    return;
  }
  const double t0 = tl.front().time, t1 = std::max(tl.back().time, t0 + 1e-9);
  double vmax = threshold > 0 ? threshold : 0;
  for (const auto& s : tl) vmax = std::max(vmax, value(s));
  if (vmax <= 0) vmax = 1;
  vmax *= 1.1;
  auto X = [&](double t) { return area.left() + (t - t0) / (t1 - t0) * area.width(); };
  auto Y = [&](double v) { return area.bottom() - v / vmax * area.height(); };
  // Axes' labels.
  p.setPen(Qt::black);
  p.drawText(QRectF(box.left(), area.top() - 20, 140, 40), Qt::AlignRight | Qt::AlignVCenter,
             number(vmax) + " " + unit);
  p.drawText(QRectF(box.left(), area.bottom() - 20, 140, 40), Qt::AlignRight | Qt::AlignVCenter, "0");
  p.drawText(QRectF(area.left() - 80, area.bottom() + 5, 160, 40), Qt::AlignCenter, number(t0) + " s");
  p.drawText(QRectF(area.right() - 80, area.bottom() + 5, 160, 40), Qt::AlignCenter, number(t1) + " s");
  if (threshold > 0) {
    p.setPen(QPen(QColor(200, 60, 60), 2, Qt::DashLine));
    p.drawLine(QPointF(area.left(), Y(threshold)), QPointF(area.right(), Y(threshold)));
  }
  // The colours the legend names (eventColour); a vessel cut's tick is longer, drawn over its cut's. The force
  // crossing the threshold first: what happened at the same step (a slip at the grasp's limit) is drawn over it.
  for (const bool crossings : {true, false})
    for (const auto& s : tl)
      for (const auto& e : s.events) {
        if ((simcore::eventKind(e) == simcore::EventKind::ForceOverThreshold) != crossings) continue;
        const QColor c = eventColour(e);
        if (!c.isValid()) continue;
        p.setPen(QPen(c, 3));
        p.drawLine(QPointF(X(s.time), area.top()), QPointF(X(s.time), area.top() + (longTick(e) ? 45 : 25)));
      }
  QPainterPath path;
  path.moveTo(X(tl.front().time), Y(value(tl.front())));
  for (const auto& s : tl) path.lineTo(X(s.time), Y(value(s)));
  p.setPen(QPen(QColor(30, 80, 200), 3));
  p.drawPath(path);
  p.restore();
}

// The report's pages as they are written: the PDF's painter, the page's size and fonts, and where the next row goes.
class ReportPages {
 public:
  ReportPages(QPdfWriter& pdf, QPainter& p) : pdf_(pdf), p_(p), W(pdf.width()), H(pdf.height()) {
    body_.setPixelSize(22);
    heading_ = body_;
    heading_.setPixelSize(34);
    heading_.setBold(true);
    bold_ = body_;
    bold_.setBold(true);
  }

  // Page 1: the session and its metrics.
  void writeFacts(const app::ReviewReport& r) {
    headline(QRectF(0, y_, W, 60), QString::fromStdString(r.title));
    y_ += 80;
    for (const auto& [k, v] : r.facts) {
      if (v.empty()) continue;
      const QString key = QString::fromStdString(k), value = QString::fromStdString(v);
      const double h = std::max(tall(290, key, 32), tall(W - 300, value, 32));
      room(h);
      put(QRectF(0, y_, 290, h), key);
      put(QRectF(300, y_, W - 300, h), value);
      y_ += h + 2;
    }
    y_ += 30;
  }

  void writeMetrics(const app::ReviewReport& r) {
    headline(QRectF(0, y_, W, 50), "Metrics");
    y_ += 60;
    const double c1 = 0, c2 = W * 0.36, c3 = W * 0.60, c4 = W * 0.82;
    p_.setFont(bold_);
    p_.drawText(QRectF(c1, y_, c2, 32), Qt::AlignLeft | Qt::AlignVCenter, "metric");
    p_.drawText(QRectF(c2, y_, c3 - c2, 32), Qt::AlignLeft | Qt::AlignVCenter, "value");
    p_.drawText(QRectF(c3, y_, c4 - c3, 32), Qt::AlignLeft | Qt::AlignVCenter, "threshold");
    p_.drawText(QRectF(c4, y_, W - c4, 32), Qt::AlignLeft | Qt::AlignVCenter, "verdict");
    y_ += 36;
    p_.setFont(body_);
    for (const auto& m : r.metrics) {
      const auto v = std::find_if(r.verdicts.begin(), r.verdicts.end(),
                                  [&](const app::Verdict& x) { return x.metric.name == m.name; });
      const QString words = QString::fromStdString(app::metricWords(m.name));
      // Counts (grasps, slips, cuts) are whole numbers: "1", not "1.000".
      const QString value = QString::fromStdString(app::metricText(m));
      const double h = std::max(tall(c2 - c1 - 10, words, 30), tall(c3 - c2 - 10, value, 30));
      room(h + 30);  // (with its note, if any)
      put(QRectF(c1, y_, c2 - c1 - 10, h), words);
      put(QRectF(c2, y_, c3 - c2 - 10, h), value);
      if (v != r.verdicts.end()) {
        QString limit;
        if (v->threshold.min) limit += ">= " + QString::fromStdString(app::metricAmount(m, *v->threshold.min)) + " ";
        if (v->threshold.max) limit += "<= " + QString::fromStdString(app::metricAmount(m, *v->threshold.max));
        p_.drawText(QRectF(c3, y_, c4 - c3, h), Qt::AlignLeft | Qt::AlignVCenter, limit);
        p_.save();
        p_.setPen(v->result == app::Verdict::Result::Pass   ? QColor(20, 130, 20)
                  : v->result == app::Verdict::Result::Fail ? QColor(190, 0, 0)
                                                            : QColor(90, 90, 90));
        p_.setFont(bold_);
        p_.drawText(QRectF(c4, y_, W - c4, h), Qt::AlignLeft | Qt::AlignVCenter, app::resultWord(v->result));
        p_.restore();
      }
      y_ += h + 2;
      if (!m.value && !m.why.empty()) {
        p_.save();
        QFont small = body_;
        small.setPixelSize(18);
        small.setItalic(true);
        p_.setFont(small);
        p_.setPen(QColor(90, 90, 90));
        const QString why = QString::fromStdString(m.why);
        const double n = tall(W - c2, why, 26);
        room(n);
        put(QRectF(c2, y_ - 4, W - c2, n), why);
        p_.restore();
        y_ += n;
      }
    }
  }

  // Page 2: plots over time.
  void writePlots(const app::ReviewReport& r) {
    pdf_.newPage();
    headline(QRectF(0, 0, W, 60), "Over time");
    plot(
        p_, QRectF(0, 80, W, H * 0.4),
        QStringLiteral("Tool force on the tissue (dashed: the threshold; %1)").arg(QLatin1String(kEventLegend)), "N",
        r.timeline, [](const app::TimelineSample& s) { return s.force; }, r.forceThresholdN);
    plot(
        p_, QRectF(0, 100 + H * 0.45, W, H * 0.4), "Largest tissue strain (principal Green strain)", "", r.timeline,
        [](const app::TimelineSample& s) { return s.strain; }, 0);
  }

  // The incorrect actions under the session's rules, each with its time (one line each, over pages as needed).
  void writeIncorrectActions(const app::ReviewReport& r) {
    pdf_.newPage();
    headline(QRectF(0, 0, W, 60), "Incorrect actions");
    y_ = 80;
    if (!r.rulesError.empty()) {
      p_.drawText(QRectF(0, y_, W, 60), Qt::AlignLeft | Qt::TextWordWrap, QString::fromStdString(r.rulesError));
      y_ += 64;
    } else if (r.incorrectActions.empty()) {
      p_.drawText(QRectF(0, y_, W, 32), Qt::AlignLeft | Qt::AlignVCenter, "None under the session's rules.");
      y_ += 36;
    }
    for (const auto& a : r.incorrectActions) {
      std::string words = a.rule;
      for (const auto& [name, w] : app::actionRuleNames())
        if (name == a.rule) words = w;
      const QString rule = QString::fromStdString(words), what = QString::fromStdString(a.what);
      p_.save();
      p_.setFont(bold_);
      const double ruleHeight = tall(W * 0.35, rule, 30);
      p_.restore();
      const double h = std::max(ruleHeight, tall(W * 0.5, what, 30));
      room(h);
      p_.save();
      p_.setPen(reviewEventColour("incorrect action: " + a.rule));
      p_.setFont(bold_);
      p_.drawText(QRectF(0, y_, W * 0.14, h), Qt::AlignLeft | Qt::AlignVCenter, number(a.time) + " s");
      put(QRectF(W * 0.14, y_, W * 0.35, h), rule);
      p_.restore();
      put(QRectF(W * 0.5, y_, W * 0.5, h), what);
      y_ += h + 4;
    }
    for (const auto& [rule, why] : r.rulesNotCounted) {
      const QString line = QString::fromStdString(rule + ": not counted, " + why);
      const double h = tall(W, line, 30);
      room(h);
      p_.save();
      p_.setPen(QColor(90, 90, 90));
      put(QRectF(0, y_, W, h), line);
      p_.restore();
      y_ += h + 2;
    }
  }

  // Page 3: key frames, two by two.
  void writeKeyFrames(const app::ReviewReport& r) {
    if (r.keyFrames.empty()) return;
    pdf_.newPage();
    headline(QRectF(0, 0, W, 60), "Key frames");
    const double cellW = W / 2 - 20, cellH = (H - 100) / 2 - 20;
    for (std::size_t k = 0; k < r.keyFrames.size() && k < 4; ++k) {
      const QImage img = toQImage(r.keyFrames[k].second);
      const double x = (k % 2) * (W / 2), yy = 80 + (k / 2) * (cellH + 40);
      QSizeF s = img.size().scaled(QSizeF(cellW, cellH - 40).toSize(), Qt::KeepAspectRatio);
      p_.drawImage(QRectF(x, yy + 40, s.width(), s.height()), img);
      p_.drawText(QRectF(x, yy, cellW, 36), Qt::AlignLeft | Qt::AlignVCenter,
                  QString::fromStdString(r.keyFrames[k].first));
    }
  }

 private:
  QPdfWriter& pdf_;
  QPainter& p_;
  const double W, H;
  QFont body_{"DejaVu Sans"}, heading_, bold_;
  double y_ = 0;

  // A page's or a section's heading in `box`; the body's font after it.
  void headline(const QRectF& box, const QString& text) {
    p_.setFont(heading_);
    p_.drawText(box, Qt::AlignLeft | Qt::AlignVCenter, text);
    p_.setFont(body_);
  }
  // Every text wraps in its column (issue 62: the replay check, a metric's note and an incorrect action's reason ran
  // off the page's edge): `tall` measures it with the painter's font, `put` draws it; a row that does not fit the
  // page starts the next one (`room`).
  double tall(double width, const QString& text, double line) const {
    return std::max(line, p_.boundingRect(QRectF(0, 0, width, 1e6), Qt::AlignLeft | Qt::TextWordWrap, text).height());
  }
  void put(const QRectF& box, const QString& text) {
    p_.drawText(box, Qt::AlignLeft | Qt::AlignVCenter | Qt::TextWordWrap, text);
  }
  void room(double height) {
    if (y_ + height > H - 10) {
      pdf_.newPage();
      y_ = 0;
    }
  }
};

}  // namespace

void writeReviewPdf(const app::ReviewReport& r, const std::string& path) {
  ensureGuiApplication();
  QByteArray bytes;
  {
    QBuffer buffer(&bytes);
    buffer.open(QIODevice::WriteOnly);
    QPdfWriter pdf(&buffer);
    pdf.setPageSize(QPageSize(QPageSize::A4));
    pdf.setResolution(150);
    pdf.setPageMargins(QMarginsF(18, 18, 18, 18), QPageLayout::Millimeter);  // a printer's margin (Qt's is 10 pt)
    pdf.setTitle(QString::fromStdString(r.title));
    pdf.setCreator("Rehearse");
    QPainter p;
    if (!p.begin(&pdf)) throw std::runtime_error("the PDF report could not be started");
    ReportPages pages(pdf, p);
    pages.writeFacts(r);
    pages.writeMetrics(r);
    pages.writePlots(r);
    pages.writeIncorrectActions(r);
    pages.writeKeyFrames(r);
    p.end();
  }
  QSaveFile out(QString::fromStdString(path));
  if (!out.open(QIODevice::WriteOnly) || out.write(bytes) != bytes.size() || !out.commit())
    throw std::runtime_error("cannot write the report " + path + ": " + out.errorString().toStdString());
}

}  // namespace rehearse::ui
