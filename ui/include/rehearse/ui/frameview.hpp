#pragma once
// Central view: the endoscope frame with the organ drawn over it through the camera, the sketched
// contour, the organ curves, attachments and landmark pairs, and whatever the current tool draws (the
// gizmo, a draft segment). CPU (QPainter) rendering, so it works over remote desktops and in offscreen
// tests. The wheel zooms about the cursor and the middle button pans in every tool; Home fits the frame.
// What a click does belongs to the current tool (frametool.hpp, one class per tool in src/tools/). Edits
// are not applied here: the tools emit the edited contour, pose or attachments through this view's
// signals and the window turns them into undoable commands.
#include "rehearse/ui/frametool.hpp"

#include <rehearse/app/case.hpp>

#include <QColor>
#include <QImage>

#include <rehearse/simcore/session/session.hpp>
#include <QWidget>

class QTimer;

#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

namespace rehearse::ui {

/// OrganCurve: clicks on the organ drawn over the frame pick the 3D curve of the nearest sketched ridge or
/// ligament (surface nodes joined by shortest paths along the surface), for the elastic fit.
/// Attachments: a click on the organ drawn over the frame holds the surface nodes around it (ligament
/// attachments for the simulation and the fit); a click on held ones releases them.
enum class Tool {
  Navigate,
  Freehand,
  ClickPoints,
  EditPoints,
  Erase,
  Align,
  Landmarks,
  OrganCurve,
  Attachments,
  Grasp,
  Scissors,
  Clip,
  Cautery
};
/// An instrument of step 7 (the grasper, scissors, clip applier or cautery hook).
inline bool isInstrument(Tool t) {
  return t == Tool::Grasp || t == Tool::Scissors || t == Tool::Clip || t == Tool::Cautery;
}

/// Gizmo handles of the Align tool: translations along and rotations about the camera axes through
/// the organ's centre of gravity.
enum class GizmoHandle { None, TranslateX, TranslateY, TranslateZ, RotateX, RotateY, RotateZ };

/// How the organ is drawn over the frame: shaded (tinted, with its outline), its visible wireframe (edges
/// of the triangles facing the camera) with the outline, or the outline alone.
enum class OverlayStyle { Shaded, Wireframe, Silhouette };

using LandmarkPair = app::LandmarkPair;

/// Step 4's keyboard nudges of the pose: arrows and PgUp/PgDn move 1 mm along the camera axes (10 mm with
/// Shift), W/S, A/D, Q/E turn 1 degree (5 with Shift) about them through the organ's centre of gravity.
/// Empty for another key or a case without pose.
std::optional<Pose> nudgedPose(const app::Case& c, int key, bool shift);

/// What tools share: set from the step pages, read by the tools.
struct ToolSettings {
  bool snapToEdges = false;                ///< new contour segments snap to image edges (intelligent scissors)
  std::string newSegmentType = "silhouette";  ///< "silhouette", "ridge" or "ligament"
  double attachmentRadius = 0.010;         ///< m: the patch one click of the Attachments tool holds or releases
};

/// The organ under a frame pixel through the current pose: the model point and its nearest surface node.
struct OrganHit {
  Eigen::Vector3d model;
  int node = -1;
};

/// One line of the frame view's legend: a colour and what it marks.
struct LegendEntry {
  QColor colour;
  QString text;
};

/// The frame view's marks (the legend names them; the drawing code uses these).
namespace palette {
inline QColor organOutline() { return QColor(120, 255, 140); }
inline QColor organFill() { return QColor(120, 210, 150); }
inline QColor landmarkOnOrgan() { return QColor(255, 150, 40); }
inline QColor landmarkInFrame() { return QColor(60, 230, 255); }
inline QColor warning() { return QColor(255, 170, 60); }  ///< a result that may be wrong (an ambiguous fit)
inline QColor possibleOutline() { return QColor(120, 190, 255); }  ///< where the organ may be (a fit's bound)
}  // namespace palette

class FrameView : public QWidget {
  Q_OBJECT
 public:
  /// The keys the view itself answers while it has the focus (keyPressEvent and its tools' key()), with what each
  /// does: the keyboard reference lists them (keyboardreference.hpp).
  static std::vector<std::pair<QString, QString>> viewKeys();
  explicit FrameView(QWidget* parent = nullptr);
  ~FrameView() override;
  void setFrame(const QImage& frame);
  /// The frame with a copy of it already scaled to frameSizeInView() (made off the GUI thread, as the composited view's
  /// worker does): drawn as it is while the view's scale stays; a copy of another size is not used.
  void setFrame(const QImage& frame, const QImage& scaledToView);
  /// The size the frame is drawn at in the view now, smoothly scaled: the size a worker scales a frame to for
  /// setFrame(frame, scaled); empty without a frame or when it is drawn enlarged (zoom 2 and over).
  QSize frameSizeInView() const;
  /// Paints that drew the frame from its scaled copy (kept, or given by setFrame(frame, scaled)) rather than through
  /// the painter's transform.
  quint64 paintsFromScaled() const { return paintsFromScaled_; }
  /// The picture under the overlay as shown now (the frame, or the composited frame).
  const QImage& shownFrame() const { return frame_; }
  /// Paints so far (the live overlay waits for its last drawing to be painted before drawing the next).
  quint64 paints() const { return paints_; }
  void setOverlay(const QImage& organ, const QList<QPolygonF>& silhouette);
  /// The inner structures' picture and, for the legend, each structure's colour and name (as in step 1).
  void setInnerOverlay(const QImage& inner, QList<QPair<QColor, QString>> key = {}) {
    inner_ = inner;
    innerKey_ = std::move(key);
    update();
  }
  /// Where the organ may be (an elastic fit's bound, app::boundOutlines): outlines in frame pixels, drawn dashed and
  /// named in the legend by `text`; empty outlines clear them.
  void setPossibleOutlines(QList<QPolygonF> outlines, const QString& text);
  const QList<QPolygonF>& possibleOutlines() const { return possible_; }
  /// Shows the case's second frame (Case::frame2) instead of the first, its contour (Case::contour2) the one drawn and
  /// edited (contourEdited then edits it), the organ not drawn over it (the camera's motion to it is the fit's to
  /// estimate). Emits shownFrameChanged.
  void setSecondFrameShown(bool second);
  bool secondFrameShown() const { return secondShown_; }
  void setCase(std::shared_ptr<const app::Case> c);
  const std::shared_ptr<const app::Case>& caseData() const { return case_; }
  /// The organ as the simulation has it now (camera frame, volume node order; empty: the case's shape): what
  /// the instruments act on.
  void setLiveShape(std::vector<Eigen::Vector3d> cameraPositions) { live_ = std::move(cameraPositions); }
  const std::vector<Eigen::Vector3d>& liveShape() const { return live_; }
  /// Nothing simulated drawn any more (Reset, another organ): the live shape, its cut surface, the clips, blood and
  /// burns, the warning; the case's organ at rest is drawn until a new frame comes.
  void clearLive();
  /// Where the simulation's instruments enter (camera frame, m; unset before a session): the scissors lay their
  /// shaft through the pressed point from there.
  void setTrocar(const std::optional<Eigen::Vector3d>& trocar) { trocar_ = trocar; }
  const std::optional<Eigen::Vector3d>& trocar() const { return trocar_; }
  /// The shafts' radius for contact (m; 0: they do not touch the tissue), as the simulation has it.
  void setShaftRadius(double r) { shaftRadius_ = r; }
  double shaftRadius() const { return shaftRadius_; }
  /// The simulation's warning over the frame: a sentence at the top and magenta rings at `cameraPoints` (camera
  /// frame, m: the elements it is about). Empty text clears it.
  void setWarning(std::vector<Eigen::Vector3d> cameraPoints, const QString& text);
  /// Step 7 is shown (true) or another step is: the rehearsal's clips, blood, burns and warning are drawn in step 7, or
  /// with an instrument in hand, only (the other steps show the case's organ; a person saw the blood of a rehearsal
  /// over step 4's overlay).
  void setRehearsing(bool on) {
    if (rehearsing_ != on) rehearsing_ = on, update();
  }
  const QString& warning() const { return warningText_; }
  /// After a cut: the live shape's boundary (its triangles index liveShape()); null before any cut.
  void setLiveSurface(std::shared_ptr<const simcore::CutSurface> s) { liveSurface_ = std::move(s); }
  const std::shared_ptr<const simcore::CutSurface>& liveSurface() const { return liveSurface_; }
  /// While rehearsing: the clips on the tissue and the blood lost from open stumps (drawn over the frame: clips in
  /// titanium grey, blood spreading over the surface from each stump, further down `gravity`, camera frame).
  /// `labels`: the elements' labels (burnt ones drawn whitened where they reach the surface).
  void setLiveField(simcore::OperativeField field, const Eigen::Vector3d& gravity,
                    std::shared_ptr<const std::vector<int>> labels = nullptr,
                    std::shared_ptr<const std::vector<std::array<int, 4>>> tets = nullptr);
  const simcore::OperativeField& liveField() const { return field_; }
  /// The elements and their labels as the simulation has them now (null before its first frame).
  const std::shared_ptr<const std::vector<std::array<int, 4>>>& liveTets() const { return fieldTets_; }
  const std::shared_ptr<const std::vector<int>>& liveLabels() const { return fieldLabels_; }
  /// Where the powered cautery hook went over the tissue, kept on the surface it touched (three nodes and barycentric
  /// weights, so it follows the tissue as it moves), one stroke per time the power came on: the burn is drawn along it.
  struct BurnTrailPoint {
    std::array<int, 3> nodes{};
    Eigen::Vector3d weights = Eigen::Vector3d::Zero();
    int stroke = 0;
  };
  /// Follows the simulation's step `step` (camera frame): the hook's tip while the power is on and the simulation's
  /// time with tissue within `radius` of it (`touchedTime`, s) grew since the last call extends the trail, at the
  /// nearest surface point. A step or a time before the last one (a reset, a new session) starts it again.
  void followHook(long step, const Eigen::Vector3d& tip, bool present, bool energy, double radius, double touchedTime);
  const std::vector<BurnTrailPoint>& burnTrail() const { return burnTrail_; }
  void clearBurnTrail() { burnTrail_.clear(), hookStep_ = -1, hookPowered_ = false, hookTouched_ = 0; }
  void setOverlayVisible(bool visible);
  bool overlayVisible() const { return overlayVisible_; }
  void setOverlayOpacity(double opacity);
  double overlayOpacity() const { return opacity_; }
  void setOverlayStyle(OverlayStyle style);
  OverlayStyle overlayStyle() const { return style_; }
  void setTool(Tool t);
  /// The instrument's gesture under way (a grasp, a stroke, a burn) ends, as if its button came up: the simulation
  /// was reset under it (a scissors stroke went on after Reset, the blade off, shoving the organ at 30 N).
  void endGesture();
  /// The simulation's jaws as its last frame has them: closed or not, holding tissue or not. Closed on nothing (the
  /// tissue slipped out, or there was none within the bite), the grasper's hold ends and it is withdrawn (after a slip
  /// the jaws had gone on dragging the shaft through the tissue with the cursor: 24-529,216 N, steps not converged; a
  /// person's check).
  void setLiveJaws(bool closed, bool holding);
  Tool tool() const { return tool_; }
  void setSnapToEdges(bool on) { settings_.snapToEdges = on; }
  /// The type new segments get: "silhouette", "ridge" or "ligament".
  void setNewSegmentType(const QString& type) { settings_.newSegmentType = type.toStdString(); }
  QString newSegmentType() const { return QString::fromStdString(settings_.newSegmentType); }
  /// Radius (m) of the patch of surface nodes one click of the Attachments tool holds or releases.
  void setAttachmentRadius(double metres) { settings_.attachmentRadius = metres; }
  double attachmentRadius() const { return settings_.attachmentRadius; }
  const ToolSettings& toolSettings() const { return settings_; }
  /// Ends the organ curve being picked (Enter, a double click or another tool do the same).
  void finishOrganCurve();
  /// Finishes the click-by-click segment being drawn (Enter does the same).
  void finishSegment();
  /// The case's landmark pairs (step 4), drawn over the frame.
  const std::vector<LandmarkPair>& landmarks() const;
  double zoom() const { return zoom_; }
  /// Frame pixel under a widget position, and back.
  QPointF toFrame(const QPointF& widgetPos) const;
  QPointF toWidget(const QPointF& framePos) const;
  /// Widget pixels per frame pixel at the current zoom.
  double scale() const;
  /// Widget position of a gizmo handle (for tests and tooltips); invalid when there is no pose.
  QPointF handlePosition(GizmoHandle h) const;
  void fitToWindow();
  /// True while a tool's work runs on a worker (a stroke snapping to image edges).
  bool toolsBusy() const;
  /// What the colours drawn now mean (the organ, each contour type present, landmarks when there are some).
  QList<LegendEntry> legend() const;
  /// The legend box in the view's bottom-left corner (widget pixels; empty when hidden or nothing is drawn).
  QRect legendRect() const;
  void setLegendVisible(bool visible);
  bool legendVisible() const { return legendVisible_; }

  // For the tools.
  /// The case's contour sized to the frame.
  imaging::Contour currentContour() const;
  /// A new id for the undo steps of one drag (they merge into one).
  int nextMergeId() { return ++mergeCounter_; }
  std::optional<OrganHit> organAt(const Eigen::Vector2d& framePixel) const;
  /// The organ's surface point under a frame pixel as the simulation has it now (the live shape, its cut boundary
  /// after a cut), snapped to the nearest surface node; camera frame (m). Nothing off the organ: what the
  /// instruments press on (and what tests aim at). `pick`: Node as above; Point, the point itself (the cautery hook
  /// glides over the surface: snapped to nodes 8 mm apart, a straight drag burnt a zigzag); OuterPoint, the point
  /// itself on the organ's outer surface (a cut's faces left out): where the scissors' shaft goes through.
  enum class SurfacePick { Node, Point, OuterPoint };
  /// `shape`: positions to pick on instead of the live shape (as many nodes; the live shape when not).
  std::optional<Eigen::Vector3d> liveSurfaceAt(const Eigen::Vector2d& framePixel, SurfacePick pick = SurfacePick::Node,
                                               const std::vector<Eigen::Vector3d>* shape = nullptr) const;
  /// Where a 3D input device holds the active instrument's tip (camera frame, m): drawn as a ring (filled while the
  /// instrument works) with its depth to the tissue under it, which the flat frame does not show; none: not drawn.
  void setDeviceTip(std::optional<Eigen::Vector3d> tip, bool working);

 signals:
  void cursorMoved(QPointF framePixel);
  /// The pointer left the view (the pixel under it is no longer shown).
  void cursorLeft();
  /// A new contour after an edit; edits with the same non-negative mergeId form one undo step.
  void contourEdited(const rehearse::imaging::Contour& contour, const QString& text, int mergeId);
  void shownFrameChanged(bool second);
  void poseEdited(const rehearse::Pose& pose, const QString& text, int mergeId);
  /// Landmarks tool: a click on the organ (model point) or, after one, on the frame (image point).
  void landmarkModelPicked(const Eigen::Vector3d& modelPoint);
  void landmarkImagePicked(const Eigen::Vector2d& imagePoint);
  /// A sentence for the status bar about the current tool (what to do next, or why a click did nothing).
  void toolMessage(const QString& text);
  /// The tool in hand changed (a button, a key, Esc).
  void toolChanged(rehearse::ui::Tool tool);
  /// Attachments tool: the organ's new attachment nodes (sorted volume node indices) after a click.
  void attachmentsEdited(const std::vector<int>& nodes, const QString& text);
  /// Rehearsal instruments: an input for the simulation session (tip pose in the camera frame, jaws).
  void instrumentInput(const rehearse::simcore::InputEvent& e);

 protected:
  void paintEvent(QPaintEvent*) override;
  /// The frame scaled to the view, kept for the repaints while it stays the same (paintEvent draws a frame that
  /// changes through the painter's transform).
  void scaleFrame();
  void wheelEvent(QWheelEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void leaveEvent(QEvent*) override;
  void mouseReleaseEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void keyPressEvent(QKeyEvent*) override;

 private:
  QTransform frameToWidget() const;
  /// True when scaledFrame_ is frame_ at the view's present scale.
  bool scaledFrameFits() const;
  FrameTool* current() const;
  void rebuildWireframe();
  void paintOverlay(QPainter& painter);
  void paintOrganMarks(QPainter& painter, const imaging::Contour& contour);
  void paintLegend(QPainter& painter);
  /// The instrument in hand named at the pointer (its tip, where it acts on the tissue).
  void paintInstrument(QPainter& painter);
  void paintDeviceTip(QPainter& painter);
  std::optional<Eigen::Vector3d> deviceTip_;
  bool deviceWorking_ = false;
  std::optional<QPointF> pointer_;  ///< widget position of the mouse while it is over the view

  std::shared_ptr<const app::Case> case_;
  std::vector<Eigen::Vector3d> live_;
  std::vector<Eigen::Vector3d> warningAt_;
  QString warningText_;
  void paintWarning(QPainter& painter);
  std::shared_ptr<const simcore::CutSurface> liveSurface_;
  simcore::OperativeField field_;
  std::vector<BurnTrailPoint> burnTrail_;
  long hookStep_ = -1;
  bool hookPowered_ = false;
  double hookTouched_ = 0;  ///< s: the simulation's time on tissue at the last frame followed
  int hookStroke_ = 0;
  double hookRadius_ = 0.003;
  /// Where a trail point is on the live shape; false when its nodes are not the live shape's.
  bool trailPlace(const BurnTrailPoint& p, Eigen::Vector3d& x) const;
  std::shared_ptr<const std::vector<int>> fieldLabels_;
  std::shared_ptr<const std::vector<std::array<int, 4>>> fieldTets_;
  Eigen::Vector3d gravity_ = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector3d> trocar_;
  double shaftRadius_ = 0;
  /// The surface's edges (fieldpaint.cpp), kept while the cut surface is the same.
  struct FieldGraph;
  std::shared_ptr<FieldGraph> fieldGraph_;
  void paintField(QPainter& painter);
  // paintField's layers (fieldpaint.cpp), each drawn over the last: the burnt faces, the burn along the hook's path,
  // the blood film, the clips.
  void paintBurntFaces(QPainter& painter);
  void paintBurnTrail(QPainter& painter);
  void paintBlood(QPainter& painter);
  void paintClips(QPainter& painter);
  /// A point of the live shape (camera frame) on the widget; none behind the camera.
  std::optional<QPointF> fieldPoint(const Eigen::Vector3d& p) const;
  /// A live-shape triangle as the camera sees it: its depth and polygon on the widget; none when it faces away or a
  /// corner is behind the camera.
  std::optional<std::pair<double, QPolygonF>> fieldFace(const std::array<int, 3>& t) const;
  QImage frame_, overlay_, inner_;
  QList<QPair<QColor, QString>> innerKey_;
  quint64 paints_ = 0, paintsFromScaled_ = 0;
  struct {
    QImage image;  ///< frame_ at the view's scale
    QPointF at;
    qint64 key = 0;
    QTransform transform;
    bool smooth = false;
  } scaledFrame_;
  QTimer* settle_ = nullptr;  ///< scales the frame once it has stayed the same a while (paintEvent)
  QList<QPolygonF> silhouette_;
  QList<QPolygonF> possible_;  ///< setPossibleOutlines
  bool secondShown_ = false;
  QString possibleText_;
  bool overlayVisible_ = true;
  bool rehearsing_ = true;  ///< setRehearsing
  bool legendVisible_ = true;
  double opacity_ = 0.45;
  OverlayStyle style_ = OverlayStyle::Shaded;
  QVector<QLineF> wire_;  // frame pixels; rebuilt when the case (pose, shape) changes
  bool wireStale_ = true;
  double zoom_ = 1.0;
  QPointF pan_;
  bool panning_ = false;
  QPointF lastMouse_;
  Tool tool_ = Tool::Navigate;
  std::map<Tool, std::unique_ptr<FrameTool>> tools_;
  ToolSettings settings_;
  int mergeCounter_ = 0;
};

}  // namespace rehearse::ui
