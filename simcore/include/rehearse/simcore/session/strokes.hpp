#pragma once
// The blade's strokes as the session words them (session.hpp; the cuts themselves: cutting.cpp): what one stroke (cut
// on to cut off, and the cuts still coming in after it) did, said when it is all in, and the rest of a sweep the blade
// finished while a cut was being built (cut when that one is in).
//
// Locking: no lock of its own; it is the stepping thread's, guarded by the session's step mutex like the body.
#include <rehearse/simcore/cut.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <string>
#include <utility>

namespace rehearse::simcore {

class StrokeTracker {
 public:
  /// What one blade stroke did, said when it is all in: whether the organ came apart, and what the stroke left uncut
  /// (inverted elements it crossed, a last sweep refused), so that "Cut" is never said over tissue that still joins.
  /// Not part of a checkpoint (it only words the message).
  struct Stroke {
    bool open = false;
    std::size_t updates = 0, split = 0, separatedFaces = 0, skippedInverted = 0, piecesBefore = 1;
    std::string lastRefusal;  ///< why the stroke's last attempt was refused (empty when its last sweep was cut)
    std::size_t sweeps = 0;   ///< sweeps the stroke asked the cut module to cut (updates: those that cut)
    std::string lastStatus;   ///< what the cut module said of the last sweep that cut nothing
  };
  using Sweep = std::pair<Eigen::Vector3d, Eigen::Vector3d>;

  /// The blade on: a new stroke, the organ in `piecesBefore` pieces.
  void begin(std::size_t piecesBefore);
  bool open() const { return stroke_.open; }
  /// One sweep the cut module was asked to cut, and what it did; a refusal is also the `message`.
  void counted(const CutResult& r, std::string& message);
  /// Ends the stroke (a new one starts closed): what it did when it was open.
  std::optional<Stroke> end();
  /// The stroke's sentence after `message`, the organ now in `pieces` pieces.
  /// `pieces`: their volumes at rest (m^3), largest first; the ones a stroke cut off are said with theirs.
  static void say(const Stroke& s, const std::vector<double>& pieces, std::string& message);

  /// The rest of a sweep asked for while a cut was being built (the blade withdrawn meanwhile): cut when it is in.
  void cutWhenIn(const Eigen::Vector3d& from, const Eigen::Vector3d& to) { restOfSweep_ = std::make_pair(from, to); }
  const std::optional<Sweep>& restOfSweep() const { return restOfSweep_; }
  /// The rest of the sweep, taken (none left).
  std::optional<Sweep> takeRestOfSweep();
  void dropRestOfSweep() { restOfSweep_.reset(); }
  /// No rest of a sweep (`rest` from a checkpoint) and no stroke (a reset, a restore).
  void clear(const std::optional<Sweep>& rest = std::nullopt);

 private:
  Stroke stroke_;
  std::optional<Sweep> restOfSweep_;
};

}  // namespace rehearse::simcore
