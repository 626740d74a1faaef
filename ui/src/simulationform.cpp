// The simulation panel's settings (simulationform.hpp).
#include "simulationform.hpp"

#include <rehearse/simcore/scene.hpp>

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QSignalBlocker>

#include <algorithm>
#include <cmath>

namespace rehearse::ui {

namespace {
// The tooltip of a field, from the scene component's declaration (the one the loader and the command line
// read): help, SI unit and default.
QString declared(const char* component, const char* parameter) {
  for (const auto& c : simcore::sceneComponents())
    if (c.type == component)
      for (const auto& p : c.parameters)
        if (p.name == parameter)
          return QStringLiteral("%1 (scene: %2.%3%4, default %5)")
              .arg(QString::fromStdString(p.help), QString::fromLatin1(component), QString::fromLatin1(parameter),
                   p.unit.empty() ? QString() : QStringLiteral(", ") + QString::fromStdString(p.unit),
                   QString::fromStdString(p.defaultValue));
  return {};
}
}  // namespace

SimulationForm::SimulationForm(QWidget* parent) : QWidget(parent) {
  form_ = new QFormLayout(this);
  form_->setContentsMargins(0, 0, 0, 0);
  addMaterialRows();
  addToolRows();
  addSolverRow();
  addGravityRows();
  connect(fields_.preset, &QComboBox::currentTextChanged, this, [this](const QString& name) {
    if (!filling_) emit presetChosen(name);
  });
  connect(fields_.model, &QComboBox::currentIndexChanged, this, &SimulationForm::relayMaterial);
  for (QDoubleSpinBox* s : {fields_.young, fields_.poisson, fields_.density, fields_.tearStrain, fields_.support})
    connect(s, &QDoubleSpinBox::valueChanged, this, &SimulationForm::relayMaterial);
  connect(fields_.method, &QComboBox::currentIndexChanged, this, &SimulationForm::relayRun);
  for (QDoubleSpinBox* s : {fields_.timeStep, fields_.jawBite, fields_.clipLength, fields_.accuracy})
    connect(s, &QDoubleSpinBox::valueChanged, this, &SimulationForm::relayRun);
  connect(fields_.density, &QDoubleSpinBox::valueChanged, this, &SimulationForm::updateMass);
  connect(fields_.start, &QCheckBox::toggled, this, &SimulationForm::startToggled);
  connect(fields_.colouring, &QComboBox::currentIndexChanged, this, &SimulationForm::colouringChosen);
  // Plausible soft-tissue values until a case arrives with its material.
  showMaterial(app::MaterialSettings{simcore::MaterialModel::Corotational, 27e3, 0.4, 1060});
}

// A numeric field whose help comes from the scene declaration; edits apply when the value is committed.
QDoubleSpinBox* SimulationForm::addField(const char* name, const QString& label, double lo, double hi, int decimals,
                                         const QString& suffix, const char* component, const char* parameter) {
  auto* f = new QDoubleSpinBox(this);
  f->setObjectName(QString::fromLatin1(name));
  f->setRange(lo, hi);
  f->setDecimals(decimals);
  f->setSuffix(suffix);
  f->setKeyboardTracking(false);
  f->setToolTip(declared(component, parameter));
  form_->addRow(label, f);
  return f;
}

// Two fields on one form row, the second named by a label between them (a row more would take room from the view).
void SimulationForm::addPair(const QString& name, QWidget* first, const QString& between, QWidget* second) {
  auto* row = new QWidget(this);
  auto* h = new QHBoxLayout(row);
  h->setContentsMargins(0, 0, 0, 0);
  h->addWidget(first, 1);
  auto* label = new QLabel(between, row);
  label->setBuddy(second);
  h->addWidget(label);
  h->addWidget(second, 1);
  form_->addRow(name, row);
}

void SimulationForm::addMaterialRows() {
  fields_.preset = new QComboBox(this);
  fields_.preset->setObjectName(QStringLiteral("simPreset"));
  for (const char* p : {"liver", "kidney", "eye", "uterus"}) fields_.preset->addItem(QString::fromLatin1(p));
  fields_.preset->setToolTip(tr("Materials of the DejaVu cases, on the current organ"));
  form_->addRow(tr("Preset"), fields_.preset);
  fields_.model = new QComboBox(this);
  fields_.model->setObjectName(QStringLiteral("simMaterial"));
  fields_.model->addItems({tr("linear"), tr("corotational"), tr("stvk"), tr("neohookean"), tr("neohookean-split")});
  fields_.model->setToolTip(declared("material", "model"));
  form_->addRow(tr("Material"), fields_.model);
  fields_.young = addField("simYoung", tr("Young's modulus"), 0.1, 100000, 1, tr(" kPa"), "material", "young");
  fields_.poisson = addField("simPoisson", tr("Poisson's ratio"), 0, 0.499, 3, QString(), "material", "poisson");
  fields_.poisson->setSingleStep(0.01);
  fields_.density = addField("simDensity", tr("Density"), 1, 20000, 0, tr(" kg/m³"), "material", "density");
  fields_.density->setToolTip(
      fields_.density->toolTip() +
      tr("\nThe presets set the tissue's density (liver 1,079 kg/m³); the organ's mass follows its volume."));
  fields_.mass = new QLabel(this);
  fields_.mass->setObjectName(QStringLiteral("simMass"));
  // Where the tissue tears: on the jaw bite's row (the grasp slips or the tissue tears, whichever comes first; a row
  // more, or a wider one, would take room from the frame view).
  fields_.tearStrain = new QDoubleSpinBox(this);
  fields_.tearStrain->setObjectName(QStringLiteral("simTearStrain"));
  fields_.tearStrain->setRange(0, 500);
  fields_.tearStrain->setDecimals(0);
  fields_.tearStrain->setSuffix(tr(" %"));
  fields_.tearStrain->setKeyboardTracking(false);
  fields_.tearStrain->setSpecialValueText(tr("never"));
  fields_.tearStrain->setAccessibleName(tr("Tears at strain"));
  fields_.tearStrain->setToolTip(
      declared("material", "tear_strain") +
      tr("\nPulled further than this, the tissue and its vessels tear (a torn vessel bleeds); the grasp slips or the "
         "tissue tears, whichever comes first. Never: it does not tear."));
  form_->addRow(tr("Organ mass"), fields_.mass);
}

void SimulationForm::addToolRows() {
  fields_.timeStep = addField("simTimeStep", tr("Time step"), 0.1, 100, 1, tr(" ms"), "implicit_euler", "dt");
  fields_.timeStep->setValue(10);
  fields_.jawBite = new QDoubleSpinBox(this);
  fields_.jawBite->setAccessibleName(tr("Jaw bite"));
  fields_.jawBite->setObjectName(QStringLiteral("simJawBite"));
  fields_.jawBite->setRange(1, 30);
  fields_.jawBite->setDecimals(1);
  fields_.jawBite->setSuffix(tr(" mm"));
  fields_.jawBite->setValue(6);
  fields_.jawBite->setKeyboardTracking(false);
  fields_.jawBite->setToolTip(
      tr("The grasper's bite: closing the jaws holds the tissue's nodes within this distance of the tip. A coarse "
         "mesh's nodes can be a centimetre apart, so a wider bite holds more of it (applies at the next grasp)"));
  addPair(tr("Jaw bite"), fields_.jawBite, tr("tears at"), fields_.tearStrain);
  fields_.clipLength = new QDoubleSpinBox(this);
  fields_.clipLength->setObjectName(QStringLiteral("simClipLength"));
  fields_.clipLength->setRange(3, 20);
  fields_.clipLength->setDecimals(1);
  fields_.clipLength->setSuffix(tr(" mm"));
  fields_.clipLength->setValue(9);
  fields_.clipLength->setKeyboardTracking(false);
  fields_.clipLength->setToolTip(
      tr("The clip applier's clips: their jaws' length across the vessel. A clip shorter than the vessel (as the mesh "
         "has it: a coarse mesh makes it wider) does not close it and is counted as misplaced (applies at the next "
         "clip)"));
  form_->addRow(tr("Clip length"), fields_.clipLength);
}

void SimulationForm::addSolverRow() {
  fields_.method = new QComboBox(this);
  fields_.method->setObjectName(QStringLiteral("simMethod"));
  // In NewtonMethod's order; chord is the default (converged every step, issue 34); linearised is faster but its one
  // solve per step is not converged (it says so: inexact above 1e-2).
  fields_.method->addItems({tr("exact Newton"), tr("lagged-PCG"), tr("chord (converged)"), tr("linearised (one solve)"),
                          tr("Newton–Krylov"), tr("precomputed linear (no cuts)"), tr("hybrid (FEM where you cut)"),
                          tr("FFD surface (no cuts)")});
  fields_.method->setCurrentIndex(static_cast<int>(simcore::kInteractiveMethod));
  fields_.method->setToolTip(
      declared("solver", "method") + QStringLiteral("\n") +
      tr("precomputed linear: Cotin's precomputed linear elasticity instead of the FEM: the "
         "organ's static answer to the instruments by superposition of responses computed when "
         "it starts, forces at haptic rate; it cannot cut, tear, clip or burn (said when asked).\n"
         "hybrid: a FEM region where the instruments work (it grows as they move and cut) coupled "
         "to the rest's precomputed responses: the linear static answer of the whole organ; it "
         "cuts, tears, clips and burns.\n"
         "FFD surface: the surface on an 81 x 81 geometry image deformed around the grasp by a "
         "Gaussian free-form deformation, Hertz's force: geometric, no equilibrium (every step says "
         "inexact); it cannot cut, tear, clip or burn"));
  form_->addRow(tr("Solver"), fields_.method);
  fields_.accuracy = new QDoubleSpinBox(this);
  fields_.accuracy->setObjectName(QStringLiteral("simAccuracy"));
  fields_.accuracy->setAccessibleName(tr("Accuracy"));
  fields_.accuracy->setRange(0, 1);
  fields_.accuracy->setDecimals(3);
  fields_.accuracy->setSingleStep(0.01);
  fields_.accuracy->setSuffix(tr(" mm"));
  fields_.accuracy->setSpecialValueText(tr("residual 1e-6"));
  fields_.accuracy->setValue(1e3 * app::SessionRequest{}.accuracy);
  fields_.accuracy->setKeyboardTracking(false);
  fields_.accuracy->setToolTip(
      tr("How close each step comes to the tissue's equilibrium: a step ends once every node is estimated within "
         "this of the converged answer and the instrument's force within 0.5 % (at least 1 mN). The status line "
         "shows each step's estimate. 0: until the relative residual is under 1e-6 (nanometres; slower)."));
  form_->addRow(tr("Accuracy"), fields_.accuracy);
}

void SimulationForm::addGravityRows() {
  fields_.gravity = new QComboBox(this);
  fields_.gravity->setObjectName(QStringLiteral("simGravity"));
  fields_.gravity->addItems({tr("down in the image"), tr("into the scene"), tr("off")});
  // A laparoscope looks down into a supine patient: gravity runs mostly along the view, into the scene.
  fields_.gravity->setCurrentIndex(1);
  fields_.gravity->setToolTip(
      tr("Gravity in the camera frame (9.81 m/s²): the organ is simulated where the frame shows it. Into the scene "
         "(the default): a laparoscope looking down into a supine patient; down in the image: a camera looking "
         "across. Stored with the case; drawn as an arrow in the 3D view"));
  fields_.support = new QDoubleSpinBox(this);
  fields_.support->setObjectName(QStringLiteral("simSupport"));
  fields_.support->setRange(0, 1e6);
  fields_.support->setDecimals(0);
  fields_.support->setSuffix(tr(" Pa/mm"));
  fields_.support->setKeyboardTracking(false);
  fields_.support->setSpecialValueText(tr("none"));
  fields_.support->setAccessibleName(tr("Carried by the tissue around it"));
  fields_.support->setToolTip(
      tr("The tissue around the organ carries it: the surface facing along gravity rests on an elastic bed of this "
         "stiffness per mm it is pressed (100 Pa/mm: a few kPa of tissue a few centimetres deep), which carries its "
         "weight where the frame shows it; the held nodes hold it too. None: only the held nodes hold it. The FEM "
         "only; a change starts the organ again."));
  form_->addRow(tr("Gravity"), fields_.gravity);
  form_->addRow(tr("Support"), fields_.support);
  connect(fields_.gravity, &QComboBox::currentIndexChanged, this, &SimulationForm::relayRun);
  // A stated choice of the case (saved with it, undoable) as well as a run parameter.
  connect(fields_.gravity, &QComboBox::currentIndexChanged, this, &SimulationForm::relayMaterial);
  fields_.start = new QCheckBox(tr("Start where the frame shows it"), this);
  fields_.start->setObjectName(QStringLiteral("simStartInEquilibrium"));
  fields_.start->setChecked(true);
  fields_.start->setToolTip(
      tr("The organ starts on the registered shape in equilibrium under gravity, held by its attachment nodes and "
         "carried by the tissue around it (Support): its rest shape is solved first, and it stays there until an "
         "instrument acts. Off: the registered shape is its rest shape, and it sags from there."));
  form_->addRow(QString(), fields_.start);
  fields_.colouring = new QComboBox(this);
  fields_.colouring->setObjectName(QStringLiteral("simColouring"));
  fields_.colouring->addItems({tr("displacement (mm)"), tr("von Mises stress (kPa)")});
  form_->addRow(tr("Colour by"), fields_.colouring);
}

void SimulationForm::relayMaterial() {
  if (!filling_) emit materialEdited();
}

void SimulationForm::relayRun() {
  if (!filling_) emit runEdited();  // a case's fields being shown: the panel acts on them once shown
}

void SimulationForm::showMaterial(const app::MaterialSettings& m) {
  filling_ = true;
  fields_.model->setCurrentIndex(static_cast<int>(m.model));
  fields_.young->setValue(m.young / 1e3);
  fields_.poisson->setValue(m.poisson);
  fields_.density->setValue(m.density);
  fields_.tearStrain->setValue(100 * m.tearStrain);
  fields_.support->setValue(m.supportModulus / 1e3);
  fields_.gravity->setCurrentIndex(static_cast<int>(m.gravity));  // (acts on the run once shown: the panel posts it)
  filling_ = false;
  updateMass();
}

app::MaterialSettings SimulationForm::material(const app::MaterialSettings& base) const {
  app::MaterialSettings m = base;
  // A field the user did not touch keeps the case's exact value (a field shows it rounded to its decimals).
  auto take = [](const QDoubleSpinBox* field, double caseValue, double scale) {
    const double shown = caseValue / scale;
    return std::abs(field->value() - shown) > 0.5 * std::pow(10.0, -field->decimals()) ? scale * field->value()
                                                                                       : caseValue;
  };
  m.model = static_cast<simcore::MaterialModel>(fields_.model->currentIndex());
  m.young = take(fields_.young, m.young, 1e3);
  m.poisson = take(fields_.poisson, m.poisson, 1.0);
  m.density = take(fields_.density, m.density, 1.0);
  m.tearStrain = take(fields_.tearStrain, m.tearStrain, 0.01);
  m.supportModulus = take(fields_.support, m.supportModulus, 1e3);
  m.gravity = static_cast<app::GravityChoice>(std::clamp(fields_.gravity->currentIndex(), 0, 2));
  return m;
}

void SimulationForm::runSettings(app::SessionRequest& s) const {
  s.timeStep = 1e-3 * fields_.timeStep->value();
  s.graspRadius = 1e-3 * fields_.jawBite->value();
  s.clipLength = 1e-3 * fields_.clipLength->value();
  // The list's entries after the Newton methods are models: the precomputed one keeps the interactive method for
  // when the FEM is chosen again.
  const int chosen = fields_.method->currentIndex();
  const int models = chosen - static_cast<int>(simcore::NewtonMethod::NewtonKrylov);  // 1 precomputed, 2 hybrid, 3 ffd
  s.method = models > 0 ? simcore::kInteractiveMethod : static_cast<simcore::NewtonMethod>(chosen);
  s.accuracy = 1e-3 * fields_.accuracy->value();
  s.bodyModel = models > 0 ? static_cast<simcore::BodyModel>(models) : simcore::BodyModel::Fem;
  static const Eigen::Vector3d directions[] = {{0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
  s.gravity = 9.81 * directions[std::clamp(fields_.gravity->currentIndex(), 0, 2)];
  s.startInEquilibrium = fields_.start->isChecked();
}

void SimulationForm::showModel(simcore::BodyModel model, simcore::NewtonMethod method) {
  const QSignalBlocker block(fields_.method);
  fields_.method->setCurrentIndex(model == simcore::BodyModel::Fem
                                      ? static_cast<int>(method)
                                      : static_cast<int>(simcore::NewtonMethod::NewtonKrylov) + static_cast<int>(model));
}

void SimulationForm::showStart(bool inEquilibrium) {
  const QSignalBlocker block(fields_.start);
  fields_.start->setChecked(inEquilibrium);
}

void SimulationForm::setOrganVolume(double volume) {
  volume_ = volume;
  updateMass();
}

void SimulationForm::updateMass() {
  fields_.mass->setText(volume_ > 0 ? tr("%1 g (%2 cm³ x density)")
                                          .arg(volume_ * fields_.density->value() * 1e3, 0, 'f', 0)
                                          .arg(volume_ * 1e6, 0, 'f', 1)
                                    : tr("no volume mesh"));
}

}  // namespace rehearse::ui
