// The review's PDF report (issue 16; below the GUI since issue 63): cairo's PDF surface with pango's text on A4 — the
// session's facts, its metrics with the trainer's thresholds and verdicts, the force and strain over time with the
// events marked, the incorrect actions, and key frames. The GUI and the GUI-less command line write the same file.
#include <rehearse/app/review.hpp>
#include <rehearse/app/incorrect_actions.hpp>
#include <rehearse/files.hpp>
#include <rehearse/simcore/session/events.hpp>

#include <cairo-pdf.h>
#include <cairo.h>
#include <pango/pangocairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

namespace rehearse::app {

std::optional<Rgb> reviewEventRgb(const std::string& e) {
  using K = simcore::EventKind;
  switch (simcore::eventKind(e)) {
    case K::Grasp: return Rgb{40, 160, 40};               // green
    case K::Release: return Rgb{40, 160, 160};            // teal
    case K::Slip: return Rgb{230, 140, 0};                // orange
    case K::Cut: return Rgb{120, 0, 160};                 // purple
    case K::VesselCut: return Rgb{200, 0, 0};             // red
    case K::ForceOverThreshold: return Rgb{90, 90, 90};   // grey
    case K::Clip: return Rgb{120, 130, 150};              // steel
    case K::ClipMisplaced: return Rgb{220, 180, 0};       // amber
    case K::Bleeding: return Rgb{110, 0, 20};             // dark red
    case K::BleedingStopped: return Rgb{230, 110, 150};   // pink
    case K::Burn: return Rgb{200, 190, 150};              // ash
    case K::EnergyOnStructure: return Rgb{255, 60, 200};  // magenta
    case K::Tear: return Rgb{150, 90, 40};                // brown
    case K::IncorrectAction: return Rgb{0, 200, 230};     // cyan
    default: return std::nullopt;
  }
}

const char* const kReviewEventLegend =
    "ticks: grasp green, release teal, slip orange, cut purple, vessel cut red (longer), force over the threshold "
    "grey, clip steel, clip misplaced amber, bleeding dark red, bleeding stopped pink, burn ash, energy on a structure "
    "magenta, tear brown, incorrect action cyan (longer)";

namespace {

// A vessel cut's and an incorrect action's ticks are longer than the others.
bool longTick(const std::string& e) {
  const simcore::EventKind k = simcore::eventKind(e);
  return k == simcore::EventKind::VesselCut || k == simcore::EventKind::IncorrectAction;
}

std::string number(double v) {
  if (v == 0) return "0";
  const double a = std::abs(v);
  char buf[64];
  if (a >= 1e4 || a < 1e-3)
    std::snprintf(buf, sizeof buf, "%.4g", v);
  else
    std::snprintf(buf, sizeof buf, "%.*f", a >= 100 ? 1 : a >= 1 ? 3 : 4, v);
  return buf;
}

struct Box {
  double x, y, w, h;
  double right() const { return x + w; }
  double bottom() const { return y + h; }
};

enum Align : unsigned { Left = 0, Right = 1, Center = 2, Top = 0, VCenter = 4, Wrap = 8 };

struct Font {
  double size = 22;  // in the page's units (150 per inch, as the Qt writer had them)
  bool bold = false, italic = false;
};

// The report's pages as they are written: cairo's PDF surface, pango's layouts, where the next row goes. Units: 150
// per inch inside an 18 mm margin (the layout the report had with Qt's writer at 150 dpi), scaled to points.
class ReportPages {
 public:
  static constexpr double kUnitsPerPoint = 150.0 / 72.0;
  static constexpr double kPageWPt = 595.2756, kPageHPt = 841.8898, kMarginPt = 18 / 25.4 * 72;

  ReportPages(cairo_surface_t* surface)
      : cr_(cairo_create(surface), cairo_destroy),
        W((kPageWPt - 2 * kMarginPt) * kUnitsPerPoint),
        H((kPageHPt - 2 * kMarginPt) * kUnitsPerPoint) {
    startPage();
  }

  void writeFacts(const ReviewReport& r) {
    headline({0, y_, W, 60}, r.title);
    y_ += 80;
    for (const auto& [k, v] : r.facts) {
      if (v.empty()) continue;
      const double h = std::max(tall(290, k, 32, body_), tall(W - 300, v, 32, body_));
      room(h);
      put({0, y_, 290, h}, k, body_);
      put({300, y_, W - 300, h}, v, body_);
      y_ += h + 2;
    }
    y_ += 30;
  }

  void writeMetrics(const ReviewReport& r) {
    headline({0, y_, W, 50}, "Metrics");
    y_ += 60;
    const double c1 = 0, c2 = W * 0.36, c3 = W * 0.60, c4 = W * 0.82;
    text({c1, y_, c2, 32}, "metric", bold_, VCenter);
    text({c2, y_, c3 - c2, 32}, "value", bold_, VCenter);
    text({c3, y_, c4 - c3, 32}, "threshold", bold_, VCenter);
    text({c4, y_, W - c4, 32}, "verdict", bold_, VCenter);
    y_ += 36;
    for (const auto& m : r.metrics) {
      const auto v = std::find_if(r.verdicts.begin(), r.verdicts.end(),
                                  [&](const Verdict& x) { return x.metric.name == m.name; });
      const std::string words = metricWords(m.name);
      const std::string value = metricText(m);  // counts as whole numbers: "1", not "1.000"
      const double h = std::max(tall(c2 - c1 - 10, words, 30, body_), tall(c3 - c2 - 10, value, 30, body_));
      room(h + 30);  // (with its note, if any)
      put({c1, y_, c2 - c1 - 10, h}, words, body_);
      put({c2, y_, c3 - c2 - 10, h}, value, body_);
      if (v != r.verdicts.end()) {
        std::string limit;
        if (v->threshold.min) limit += ">= " + metricAmount(m, *v->threshold.min) + " ";
        if (v->threshold.max) limit += "<= " + metricAmount(m, *v->threshold.max);
        text({c3, y_, c4 - c3, h}, limit, body_, VCenter);
        colour(v->result == Verdict::Result::Pass   ? Rgb{20, 130, 20}
               : v->result == Verdict::Result::Fail ? Rgb{190, 0, 0}
                                                    : Rgb{90, 90, 90});
        text({c4, y_, W - c4, h}, resultWord(v->result), bold_, VCenter);
        colour({0, 0, 0});
      }
      y_ += h + 2;
      if (!m.value && !m.why.empty()) {
        const Font small{18, false, true};
        const double n = tall(W - c2, m.why, 26, small);
        room(n);
        colour({90, 90, 90});
        put({c2, y_ - 4, W - c2, n}, m.why, small);
        colour({0, 0, 0});
        y_ += n;
      }
    }
  }

  // Page 2: plots over time.
  void writePlots(const ReviewReport& r) {
    newPage();
    headline({0, 0, W, 60}, "Over time");
    plot({0, 80, W, H * 0.4},
         std::string("Tool force on the tissue (dashed: the threshold; ") + kReviewEventLegend + ")", "N", r.timeline,
         [](const TimelineSample& s) { return s.force; }, r.forceThresholdN);
    plot({0, 100 + H * 0.45, W, H * 0.4}, "Largest tissue strain (principal Green strain)", "", r.timeline,
         [](const TimelineSample& s) { return s.strain; }, 0);
  }

  // The incorrect actions under the session's rules, each with its time (one row each, over pages as needed).
  void writeIncorrectActions(const ReviewReport& r) {
    newPage();
    headline({0, 0, W, 60}, "Incorrect actions");
    y_ = 80;
    if (!r.rulesError.empty()) {
      const double h = tall(W, r.rulesError, 60, body_);
      put({0, y_, W, h}, r.rulesError, body_);
      y_ += h + 4;
    } else if (r.incorrectActions.empty()) {
      text({0, y_, W, 32}, "None under the session's rules.", body_, VCenter);
      y_ += 36;
    }
    for (const auto& a : r.incorrectActions) {
      std::string words = a.rule;
      for (const auto& [name, w] : actionRuleNames())
        if (name == a.rule) words = w;
      const double h = std::max(tall(W * 0.35, words, 30, bold_), tall(W * 0.5, a.what, 30, body_));
      room(h);
      colour(reviewEventRgb("incorrect action: " + a.rule).value_or(Rgb{0, 0, 0}));
      text({0, y_, W * 0.14, h}, number(a.time) + " s", bold_, VCenter);
      put({W * 0.14, y_, W * 0.35, h}, words, bold_);
      colour({0, 0, 0});
      put({W * 0.5, y_, W * 0.5, h}, a.what, body_);
      y_ += h + 4;
    }
    for (const auto& [rule, why] : r.rulesNotCounted) {
      const std::string line = rule + ": not counted, " + why;
      const double h = tall(W, line, 30, body_);
      room(h);
      colour({90, 90, 90});
      put({0, y_, W, h}, line, body_);
      colour({0, 0, 0});
      y_ += h + 2;
    }
  }

  // Key frames, two by two.
  void writeKeyFrames(const ReviewReport& r) {
    if (r.keyFrames.empty()) return;
    newPage();
    headline({0, 0, W, 60}, "Key frames");
    const double cellW = W / 2 - 20, cellH = (H - 100) / 2 - 20;
    for (std::size_t k = 0; k < r.keyFrames.size() && k < 4; ++k) {
      const cv::Mat3b& img = r.keyFrames[k].second;
      const double x = static_cast<double>(k % 2) * (W / 2), yy = 80 + static_cast<double>(k / 2) * (cellH + 40);
      text({x, yy, cellW, 36}, r.keyFrames[k].first, body_, VCenter);
      if (img.empty()) continue;
      const double scale = std::min(cellW / img.cols, (cellH - 40) / img.rows);
      image(img, x, yy + 40, scale);
    }
  }

  cairo_status_t status() const { return cairo_status(cr_.get()); }

 private:
  std::unique_ptr<cairo_t, void (*)(cairo_t*)> cr_;
  const double W, H;
  const Font body_{22, false, false}, bold_{22, true, false}, heading_{34, true, false};
  double y_ = 0;

  void startPage() {
    cairo_identity_matrix(cr_.get());
    cairo_translate(cr_.get(), kMarginPt, kMarginPt);
    cairo_scale(cr_.get(), 1 / kUnitsPerPoint, 1 / kUnitsPerPoint);
    colour({0, 0, 0});
  }
  void newPage() {
    cairo_show_page(cr_.get());
    startPage();
    y_ = 0;
  }
  void colour(Rgb c) { cairo_set_source_rgb(cr_.get(), c.r / 255.0, c.g / 255.0, c.b / 255.0); }

  // A pango layout of `s` in `font`, `width` wide (wrapping at words) when wrap is asked.
  std::unique_ptr<PangoLayout, void (*)(void*)> layout(const std::string& s, const Font& font, double width,
                                                       unsigned align) const {
    PangoLayout* l = pango_cairo_create_layout(cr_.get());
    PangoFontDescription* d = pango_font_description_from_string("DejaVu Sans");
    pango_font_description_set_absolute_size(d, font.size * PANGO_SCALE);
    pango_font_description_set_weight(d, font.bold ? PANGO_WEIGHT_BOLD : PANGO_WEIGHT_NORMAL);
    pango_font_description_set_style(d, font.italic ? PANGO_STYLE_ITALIC : PANGO_STYLE_NORMAL);
    pango_layout_set_font_description(l, d);
    pango_font_description_free(d);
    pango_layout_set_width(l, static_cast<int>(width * PANGO_SCALE));
    pango_layout_set_wrap(l, PANGO_WRAP_WORD_CHAR);
    if (!(align & Wrap)) pango_layout_set_ellipsize(l, PANGO_ELLIPSIZE_END);  // one line, never past its box
    pango_layout_set_alignment(l, (align & Center)  ? PANGO_ALIGN_CENTER
                                  : (align & Right) ? PANGO_ALIGN_RIGHT
                                                    : PANGO_ALIGN_LEFT);
    pango_layout_set_text(l, s.c_str(), -1);
    return {l, g_object_unref};
  }
  // The height `s` takes wrapped in `width` (at least `line`).
  double tall(double width, const std::string& s, double line, const Font& font) const {
    int w = 0, h = 0;
    pango_layout_get_size(layout(s, font, width, Wrap).get(), &w, &h);
    return std::max(line, static_cast<double>(h) / PANGO_SCALE);
  }
  void text(const Box& b, const std::string& s, const Font& font, unsigned align) {
    auto l = layout(s, font, b.w, align);
    int w = 0, h = 0;
    pango_layout_get_size(l.get(), &w, &h);
    const double th = static_cast<double>(h) / PANGO_SCALE;
    cairo_move_to(cr_.get(), b.x, (align & VCenter) ? b.y + (b.h - th) / 2 : b.y);
    pango_cairo_show_layout(cr_.get(), l.get());
  }
  // Text wrapped in its column (issue 62: nothing runs off the page's edge).
  void put(const Box& b, const std::string& s, const Font& font) { text(b, s, font, Wrap | VCenter); }
  void headline(const Box& b, const std::string& s) { text(b, s, heading_, VCenter); }
  // A row that does not fit the page starts the next one.
  void room(double height) {
    if (y_ + height > H - 10) newPage();
  }
  void line(double x0, double y0, double x1, double y1) {
    cairo_move_to(cr_.get(), x0, y0);
    cairo_line_to(cr_.get(), x1, y1);
    cairo_stroke(cr_.get());
  }

  void image(const cv::Mat3b& img, double x, double y, double scale) {
    cairo_surface_t* s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, img.cols, img.rows);
    cairo_surface_flush(s);
    unsigned char* data = cairo_image_surface_get_data(s);
    const int stride = cairo_image_surface_get_stride(s);
    for (int r = 0; r < img.rows; ++r) {
      auto* row = reinterpret_cast<std::uint32_t*>(data + static_cast<std::ptrdiff_t>(r) * stride);
      for (int c = 0; c < img.cols; ++c) {
        const cv::Vec3b& p = img(r, c);  // BGR
        row[c] = 0xff000000u | (std::uint32_t{p[2]} << 16) | (std::uint32_t{p[1]} << 8) | p[0];
      }
    }
    cairo_surface_mark_dirty(s);
    cairo_save(cr_.get());
    cairo_translate(cr_.get(), x, y);
    cairo_scale(cr_.get(), scale, scale);
    cairo_set_source_surface(cr_.get(), s, 0, 0);
    cairo_paint(cr_.get());
    cairo_restore(cr_.get());
    cairo_surface_destroy(s);
  }

  // A plot of one series over time, the events marked as ticks along the top.
  void plot(const Box& box, const std::string& title, const std::string& unit, const std::vector<TimelineSample>& tl,
            double (*value)(const TimelineSample&), double threshold) {
    cairo_t* cr = cr_.get();
    // The title wraps (its legend is long): the plot starts below however many lines it takes.
    const double titleH = tall(box.w, title, 32, body_);
    text({box.x, box.y, box.w, titleH}, title, body_, Wrap);
    const double top = titleH + 10;
    const Box area{box.x + 150, box.y + top, box.w - 200, box.h - top - 50};
    cairo_set_line_width(cr, 2);
    cairo_rectangle(cr, area.x, area.y, area.w, area.h);
    cairo_stroke(cr);
    if (tl.empty()) {
      text(area, "no samples", body_, Center | VCenter);
      return;
    }
    const double t0 = tl.front().time, t1 = std::max(tl.back().time, t0 + 1e-9);
    double vmax = threshold > 0 ? threshold : 0;
    for (const auto& s : tl) vmax = std::max(vmax, value(s));
    if (vmax <= 0) vmax = 1;
    vmax *= 1.1;
    auto X = [&](double t) { return area.x + (t - t0) / (t1 - t0) * area.w; };
    auto Y = [&](double v) { return area.bottom() - v / vmax * area.h; };
    // Axes' labels.
    text({box.x, area.y - 20, 140, 40}, number(vmax) + (unit.empty() ? "" : " " + unit), body_, Right | VCenter);
    text({box.x, area.bottom() - 20, 140, 40}, "0", body_, Right | VCenter);
    text({area.x - 80, area.bottom() + 5, 160, 40}, number(t0) + " s", body_, Center | VCenter);
    text({area.right() - 80, area.bottom() + 5, 160, 40}, number(t1) + " s", body_, Center | VCenter);
    if (threshold > 0) {
      cairo_save(cr);
      colour({200, 60, 60});
      const double dash[] = {8, 6};
      cairo_set_dash(cr, dash, 2, 0);
      line(area.x, Y(threshold), area.right(), Y(threshold));
      cairo_restore(cr);
    }
    // The colours the legend names; a vessel cut's tick is longer, drawn over its cut's. The force crossing the
    // threshold first: what happened at the same step (a slip at the grasp's limit) is drawn over it.
    cairo_set_line_width(cr, 3);
    for (const bool crossings : {true, false})
      for (const auto& s : tl)
        for (const auto& e : s.events) {
          if ((simcore::eventKind(e) == simcore::EventKind::ForceOverThreshold) != crossings) continue;
          const std::optional<Rgb> c = reviewEventRgb(e);
          if (!c) continue;
          colour(*c);
          line(X(s.time), area.y, X(s.time), area.y + (longTick(e) ? 45 : 25));
        }
    colour({30, 80, 200});
    cairo_move_to(cr, X(tl.front().time), Y(value(tl.front())));
    for (const auto& s : tl) cairo_line_to(cr, X(s.time), Y(value(s)));
    cairo_stroke(cr);
    colour({0, 0, 0});
  }
};

cairo_status_t appendBytes(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

void writeReviewPdf(const ReviewReport& r, const std::string& path) {
  std::string bytes;
  {
    std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> surface(
        cairo_pdf_surface_create_for_stream(appendBytes, &bytes, ReportPages::kPageWPt, ReportPages::kPageHPt),
        cairo_surface_destroy);
    cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_TITLE, r.title.c_str());
    cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_CREATOR, "Rehearse");
    ReportPages pages(surface.get());
    pages.writeFacts(r);
    pages.writeMetrics(r);
    pages.writePlots(r);
    pages.writeIncorrectActions(r);
    pages.writeKeyFrames(r);
    if (pages.status() != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(std::string("the PDF report could not be drawn (") +
                               cairo_status_to_string(pages.status()) + ")");
    cairo_surface_finish(surface.get());
    if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(std::string("the PDF report could not be written (") +
                               cairo_status_to_string(cairo_surface_status(surface.get())) + ")");
  }
  writeFileAtomically(path, bytes);  // (its sentence names the file and what to check)
}

}  // namespace rehearse::app
