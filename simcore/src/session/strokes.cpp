#include <rehearse/simcore/session/strokes.hpp>
#include <rehearse/simcore/words.hpp>

#include <algorithm>
#include <cstdio>

namespace rehearse::simcore {

void StrokeTracker::begin(std::size_t piecesBefore) {
  stroke_ = {};
  stroke_.open = true;
  stroke_.piecesBefore = piecesBefore;
}

void StrokeTracker::counted(const CutResult& r, std::string& message) {
  ++stroke_.sweeps;
  if (!r.changed) {
    stroke_.lastStatus = r.status;
    if (r.status.rfind("The cut was refused", 0) == 0) message = stroke_.lastRefusal = r.status;
    return;
  }
  ++stroke_.updates;
  stroke_.split += r.splitElements;
  stroke_.separatedFaces += r.separatedFaces;
  stroke_.skippedInverted += r.skippedInverted;
  stroke_.lastRefusal.clear();
}

std::optional<StrokeTracker::Stroke> StrokeTracker::end() {
  const Stroke s = stroke_;
  stroke_ = {};
  if (!s.open) return std::nullopt;
  return s;
}

std::optional<StrokeTracker::Sweep> StrokeTracker::takeRestOfSweep() {
  std::optional<Sweep> rest = restOfSweep_;
  restOfSweep_.reset();
  return rest;
}

void StrokeTracker::clear(const std::optional<Sweep>& rest) {
  restOfSweep_ = rest;
  stroke_ = {};
}

namespace {
// "The blade crossed no tissue." after a colon: "the blade crossed no tissue."
std::string lowerFirst(std::string s) {
  if (!s.empty() && s[0] >= 'A' && s[0] <= 'Z') s[0] = static_cast<char>(s[0] - 'A' + 'a');
  return s;
}
constexpr double kFragmentShare = 0.01;  // of the organ's volume: a smaller piece is a fragment
}  // namespace

void StrokeTracker::say(const Stroke& s, const std::vector<double>& volumes, std::string& message) {
  const std::size_t pieces = volumes.size();
  std::string m;
  if (s.updates == 0 && !s.lastRefusal.empty()) {
    m = "Nothing was cut: " + s.lastRefusal;
  } else if (s.updates == 0) {
    // A stroke that opened nothing is said too: the surgeon swept the blade and the tissue did not change.
    m = s.sweeps == 0
            ? "Nothing was cut: the blade did not move while it was on."
            : "Nothing was cut: " +
                  (s.lastStatus.empty() ? std::string("the blade opened no face.") : lowerFirst(s.lastStatus)) +
                  " The blade reaches from its tip back along the shaft: take it deeper into the tissue (the "
                  "wheel, in the view) or stroke further across it.";
  } else {
    m = "The cut is done: " + quantity(static_cast<std::size_t>(s.separatedFaces), "face", "faces") + " opened and " +
        quantity(static_cast<std::size_t>(s.split), "element", "elements") + " split in " +
        quantity(static_cast<std::size_t>(s.updates), "update", "updates") + "; ";
    // What came off, by its volume: a sliver at the organ's thin edge said apart from a lobe (a person read "the
    // organ came apart (2 pieces)" and could not tell which).
    std::string off;
    // A volume in words: "0.0 mL" read as no piece at all (a person's check), a sliver under 0.1 mL is said so.
    auto mL = [](double v) {
      char buf[32];
      if (1e6 * v < 0.05) return std::string("under 0.1 mL");
      std::snprintf(buf, sizeof buf, "%.1f mL", 1e6 * v);
      return std::string(buf);
    };
    if (pieces > s.piecesBefore) {
      off = ": the largest piece is " + mL(volumes.front()) + ", the smallest";
      const std::size_t shown = std::min<std::size_t>(pieces - 1, 3);
      for (std::size_t k = 0; k < shown; ++k)
        off += std::string(k == 0 ? " " : k + 1 == shown ? " and " : ", ") + mL(volumes[pieces - 1 - k]);
    }
    // Pieces under 1 % of the organ are fragments the blade chipped off, not the organ coming apart (a person's three
    // shallow strokes across the phantom each read "the organ came apart", its smallest pieces 0.1-0.3 mL of 415).
    double total = 0;
    for (double v : volumes) total += v;
    std::size_t fragments = 0;
    for (std::size_t k = 1; k < pieces; ++k) fragments += volumes[k] < kFragmentShare * total;
    const bool chipped = pieces > s.piecesBefore && fragments + 1 == pieces;
    // (The fragments this stroke chipped off said apart from the earlier ones: "(8 pieces, 4 before)" counted the
    // fragments as pieces.)
    const std::size_t chippedNow = pieces - s.piecesBefore;
    m += chipped ? "the organ is in one piece but for " +
                       std::string(fragments == 1 ? "a fragment" : std::to_string(fragments) + " fragments") +
                       " under 1 % of it (" +
                       (chippedNow == fragments ? std::string(fragments == 1 ? "chipped" : "all chipped") +
                                                      " off by this stroke"
                                                : std::to_string(chippedNow) + " chipped off by this stroke") +
                       ")" + off + "."
         : pieces > s.piecesBefore
             ? "the organ came apart (" + std::to_string(pieces) + " pieces, " + std::to_string(s.piecesBefore) +
                   " before)" + off + "."
             // Its pieces of 1 % or more, the fragments said apart (a person read "still in 3 pieces" of an organ in
             // one piece but for two chips from earlier strokes).
             : "the organ is still in " +
                   std::string(pieces - fragments == 1 ? "one piece" : std::to_string(pieces - fragments) + " pieces") +
                   (fragments == 0 ? std::string()
                                   : " besides " + std::string(fragments == 1 ? "a fragment" : std::to_string(fragments) + " fragments") +
                                         " under 1 % of it") +
                   " (the cut did not go through).";
    if (s.skippedInverted > 0)
      m += " " + (s.skippedInverted == 1 ? std::string("1 crossed element was")
                                          : std::to_string(s.skippedInverted) + " crossed elements were") +
           " inverted and not cut: tissue still joins there.";
    if (!s.lastRefusal.empty()) m += " The stroke's last sweep was not cut: " + s.lastRefusal;
  }
  if (!message.empty()) message += " ";
  message += m;
}

}  // namespace rehearse::simcore
