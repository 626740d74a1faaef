#pragma once
// What the simulation panel shows of a running session: a frame made from each published snapshot (on the session's
// thread: positions, the coloured quantity per node, what happened) and the view that draws it (the deformed organ
// coloured by displacement or von Mises stress, turned like the organ view).
#include <rehearse/app/case.hpp>
#include "rehearse/ui/organview.hpp"

#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QFontMetrics>
#include <QRect>
#include <QString>
#include <QWidget>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace rehearse::ui {

/// Published after each step: positions and the coloured quantity per node.
struct SimulationFrame {
  std::vector<Eigen::Vector3d> positions;  ///< per node, camera frame (m)
  std::vector<double> value;               ///< per node: displacement (mm) or von Mises (kPa)
  double valueMax = 0;
  /// Top of the colour bar: the displacement's largest (at least 1 mm), the stress's 98th percentile (it peaks at the
  /// attachments).
  double valueScale = 0;
  int colouring = 0;      ///< 0 displacement, 1 von Mises
  simcore::StepReport report;
  double time = 0;  ///< simulated time (s)
  long steps = 0;
  double youngInUse = 0;        ///< Pa (shows when a live edit took effect)
  Qt::HANDLE thread = nullptr;  ///< the thread that computed it (never the GUI thread)
  std::shared_ptr<const app::Case> organ;
  QString message;                  ///< the session's sentence about the last applied input, if any
  simcore::ToolState tool;          ///< the instrument after the step (tip, held nodes, force on the tissue)
  std::vector<std::string> events;  ///< grasp, release, slip, cut, vessel cut at this step
  std::shared_ptr<const simcore::CutSurface> surface;  ///< after a cut: the boundary to draw (cut tissue marked)
  simcore::OperativeField field;                       ///< clips, bleeding stumps, blood lost, the cautery's heat
  std::shared_ptr<const std::vector<int>> labels;      ///< the elements' labels (burnt ones: simcore::isBurnt)
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();   ///< m/s^2, camera frame
  /// The nodes the tissue around the organ carries (BodySetup::supports; drawn beneath the organ), none without.
  std::shared_ptr<const std::vector<int>> supports;
  /// The nodes the session holds fixed (BodySetup::fixedNodes): the case's attachments and, around a lone pick, its
  /// neighbours on the surface (app::StartOptions::attachmentPatches), drawn smaller than the picks.
  std::shared_ptr<const std::vector<int>> held;
  /// Steps since the start (or the last Reset) that did not converge to the scene's tolerance: every step counted,
  /// whether or not its frame was drawn.
  long stepsNotConverged = 0;
  std::size_t elements = 0;
  std::uint64_t responseKey = 0;  ///< the precomputed model's responses (simcore::ResponseCache), 0 for the FEM
  simcore::BodyModel model = simcore::BodyModel::Fem;           ///< the deformable model that ran the step
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();             ///< where the instruments enter (camera frame, m)
  double toolRadius = 0;                                        ///< m: the shafts' radius for contact
  double mass = 0;                                              ///< kg
  double maxGraspForce = 0;                                     ///< N: the jaws let go above it (ToolSettings)
  std::shared_ptr<const std::vector<std::array<int, 4>>> tets;  ///< the elements at this step
  /// Elements inside out after this step (when the report counts any): their indices, their nodes (per node, 1 when
  /// one of its elements is) and their centroids (camera frame, m), for the warning drawn on the organ.
  std::vector<int> inverted;
  std::vector<char> invertedNode;
  std::vector<Eigen::Vector3d> invertedAt;
};

/// The warning a frame's step calls for, in one sentence (empty when none): elements inside out, or a step held back
/// to keep them from inverting. Shown on the organ in the simulation view and over the frame in step 7.
QString warningText(const SimulationFrame& f);

/// Draws a SimulationFrame: the organ's surface with the frame's positions, per-vertex colours and a
/// colour bar; turntable controls as in the organ view.
class SimulationView : public QWidget {
  Q_OBJECT
 public:
  explicit SimulationView(QWidget* parent = nullptr);
  void setFrame(std::shared_ptr<const SimulationFrame> f);
  /// No frame, and why (drawn in its place; empty: the invitation to start).
  void clearFrame(const QString& why);
  QSize sizeHint() const override { return {420, 320}; }
  /// Where the view's top-left marks go (the time line, the gravity arrow and its word, the supports' caption), in a
  /// view of any size.
  static QRect marksArea();
  /// Where a warning (warningText) is drawn in a view of `size` with the font `fm`: along the bottom, left of the colour
  /// bar, as many lines as it wraps to (over the gravity arrow it hid its word, a person's check).
  static QRect warningArea(const QSize& size, const QFontMetrics& fm, const QString& text);

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;

 private:
  std::shared_ptr<const SimulationFrame> frame_;
  QString emptyText_;
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();  ///< the organ's centre of gravity (m)
  double size_ = 0.05;                                ///< its bounding sphere's radius (m), from the first frame
  Turntable turntable_;
};

/// What turns one session's snapshots into frames: fixed for one organ (one session), read on the session's thread.
struct FrameBasis {
  std::shared_ptr<const app::Case> organ;
  std::vector<Eigen::Vector3d> rest;  ///< where the rehearsal starts, camera frame (m): displacements from it
  std::vector<std::array<int, 4>> tets;
  std::vector<int> incidence;  ///< elements per node (stress averaged onto nodes)
  std::shared_ptr<const std::vector<int>> supports;  ///< the supported nodes (kept by index through cuts)
  std::shared_ptr<const std::vector<int>> held;      ///< the held nodes (BodySetup::fixedNodes, kept by index)
  double maxGraspForce = 0;                          ///< N (ToolSettings::maxGraspForce)
  /// After a cut: the pieces of the elements `piecesOf` (simcore::nodePieces), made again when they change, and whether
  /// a held or supported node carries each.
  std::shared_ptr<const std::vector<std::array<int, 4>>> piecesOf;
  std::vector<int> piece;
  std::vector<char> pieceHeld;
  long generation = 0;         ///< frames of an older session are dropped
  // On the session's thread (its published callback, once per step): steps not converged since the start or a Reset.
  long lastStep = 0, notConverged = 0;
};

/// The basis of the frames of a session started on `body` (its setup as started) for the case `organ`.
FrameBasis frameBasis(std::shared_ptr<const app::Case> organ, const simcore::BodySetup& body, long generation);

/// The frame of one snapshot, coloured by displacement (`colouring` 0) or von Mises stress (1); counts the steps not
/// converged in `basis`.
std::shared_ptr<const SimulationFrame> makeSimulationFrame(FrameBasis& basis, const simcore::Snapshot& snap,
                                                           int colouring);

}  // namespace rehearse::ui
