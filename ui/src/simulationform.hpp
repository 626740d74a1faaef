#pragma once
// The simulation panel's settings (a part of the panel, private to ui/): the case's material (model, moduli, density,
// where it tears, the tissue around it), the run's settings (time step, jaw bite, clip length, solver, gravity, how it
// starts) and the colouring, each with its help from the scene's declarations. It only shows and asks: what is edited
// goes out as signals (never while a case's values are being shown).
#include <rehearse/app/case.hpp>
#include <rehearse/app/sessionstart.hpp>

#include <QString>
#include <QWidget>

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QFormLayout;
class QLabel;

namespace rehearse::ui {

class SimulationForm : public QWidget {
  Q_OBJECT
 public:
  explicit SimulationForm(QWidget* parent = nullptr);

  /// Shows a case's material (no signal while it is filled in).
  void showMaterial(const app::MaterialSettings& m);
  /// The material the fields show, on `base` (a field the user did not touch keeps base's exact value).
  app::MaterialSettings material(const app::MaterialSettings& base) const;
  /// The run's settings the fields show into `s` (time step, jaw bite, clip length, solver and model, gravity, start).
  void runSettings(app::SessionRequest& s) const;
  /// The solver list shows what runs (a model refused or its build cancelled), with no signal.
  void showModel(simcore::BodyModel model, simcore::NewtonMethod method);
  /// The start check box set back (no signal): a recorded session's start is not changed under it.
  void showStart(bool inEquilibrium);
  /// The organ's volume (m^3; 0: none) for the mass the density gives.
  void setOrganVolume(double volume);
  bool filling() const { return filling_; }

 signals:
  void materialEdited();  ///< a material field (or gravity: a stated choice of the case) was committed
  void runEdited();       ///< a run setting (time step, jaw bite, clip length, solver, gravity) was committed
  void startToggled(bool inEquilibrium);
  void presetChosen(const QString& name);
  void colouringChosen(int colouring);  ///< 0 displacement, 1 von Mises stress

 private:
  void addMaterialRows();
  void addToolRows();
  void addSolverRow();
  void addGravityRows();
  QDoubleSpinBox* addField(const char* name, const QString& label, double lo, double hi, int decimals,
                           const QString& suffix, const char* component, const char* parameter);
  void addPair(const QString& name, QWidget* first, const QString& between, QWidget* second);
  void relayMaterial();
  void relayRun();
  void updateMass();

  QFormLayout* form_ = nullptr;
  struct Fields {
    QComboBox* preset = nullptr;
    QComboBox* model = nullptr;
    QComboBox* method = nullptr;
    QComboBox* colouring = nullptr;
    QComboBox* gravity = nullptr;
    QCheckBox* start = nullptr;  ///< start where the frame shows it (SessionRequest::startInEquilibrium)
    QDoubleSpinBox* young = nullptr;
    QDoubleSpinBox* poisson = nullptr;
    QDoubleSpinBox* density = nullptr;
    QDoubleSpinBox* tearStrain = nullptr;  ///< % strain the tissue tears at (0: never)
    QDoubleSpinBox* support = nullptr;     ///< Pa/mm: the tissue around the organ carries it (0: none)
    QDoubleSpinBox* timeStep = nullptr;
    QDoubleSpinBox* jawBite = nullptr;  ///< the grasper's reach: closing holds the nodes within it of the tip (mm)
    QDoubleSpinBox* clipLength = nullptr;  ///< the clip applier's jaws' length (mm)
    QDoubleSpinBox* accuracy = nullptr;    ///< mm: the accuracy a step is asked for (0: the relative residual alone)
    QLabel* mass = nullptr;  ///< density x the organ's volume, so a preset's density reads as the mass it gives
  } fields_;
  double volume_ = 0;  ///< m^3
  bool filling_ = false;
};

}  // namespace rehearse::ui
