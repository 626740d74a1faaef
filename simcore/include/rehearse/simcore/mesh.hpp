#pragma once
// Mesh as loaded or generated: one container for surfaces and volumes.
#include <rehearse/types.hpp>

#include <array>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rehearse::simcore {

/// A user-facing mesh error: `what()` is one sentence that says what is wrong and what to do.
/// What an element label is (issue 36), from its name: what a cut, a clip or energy on it is judged by. Parts and
/// labels come named from the imported file (glTF nodes, Gmsh physical names, a case's label table).
enum class StructureKind { Tissue, Ligament, Vessel, Artery, Vein, PortalVein, BileDuct, Tumour, TumourMargin };
/// The kind a name says, case and separators ignored: a ligament first ("ligamentum venosum", "round ligament": not
/// vessels, though named after the veins they were), then a tumour's or resection's margin (not an organ's border: "the
/// inferior margin of the liver" is tissue), a bile duct ("CBD", "cystic duct",
/// "biliary"), the portal vein ("portal", "PV"; not "porta hepatis"), an artery ("hepatic artery", "aorta", "HA"), a
/// vein ("vein", "venous", "cava", "IVC", "HV"), a vessel of no stated kind ("vessels", "vascular"), a tumour
/// ("tumour", "tumor", "lesion", "metastasis", "carcinoma", "nodule"); anything else (unnamed too) is tissue.
StructureKind structureKind(const std::string& name);
/// "tissue", "ligament", "vessel", "artery", "vein", "portal vein", "bile duct", "tumour", "tumour margin".
const char* structureKindName(StructureKind kind);
/// A structure as a sentence names it: its label's name when that says the kind ("hepatic artery", "common bile
/// duct"), the kind alone when the name only repeats it ("vessel" for "vessels"), else the kind and the name ("vessel
/// (left branch)").
std::string structureWords(StructureKind kind, const std::string& labelName);
/// "A" or "An" before `words`.
const char* indefiniteArticle(const std::string& words);
/// A blood vessel: vessel, artery, vein or portal vein.
bool isVessel(StructureKind kind);

struct MeshError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Points plus triangles and/or tetrahedra. A surface has no tets; a volume may also carry boundary
/// triangles from its file. Labels: per element integer (part index for surfaces from multi-part
/// files, physical/region tag for volumes); `labelNames` maps a label to a name when one is known.
struct Mesh {
  std::vector<Eigen::Vector3d> points;        // file order, in `unit` until scaled
  std::vector<std::array<int, 3>> triangles;  // 0-based point indices
  std::vector<int> triangleLabels;            // same size as triangles
  std::vector<std::array<int, 4>> tets;       // 0-based point indices, positive orientation
  std::vector<int> tetLabels;                 // same size as tets
  std::vector<std::pair<int, std::string>> labelNames;
  double unitToMetre = 1.0;  // coordinates * unitToMetre = metres

  bool isVolume() const { return !tets.empty(); }
  bool empty() const { return points.empty(); }
  std::string labelName(int label) const;
  void setLabelName(int label, const std::string& name);
  /// The label's kind, from its name (structureKind).
  StructureKind labelKind(int label) const;
  /// Whether the label's name says it is a blood vessel ("vessels", "portal vein", "hepatic artery", "IVC"...): how a
  /// cut through a vessel is told from a cut through any other inner structure. Unnamed labels are not vessels.
  bool labelIsVessel(int label) const;
  /// Whether any label is named as a vessel (else a session cannot say whether a vessel was cut).
  bool namesAVessel() const;
  SurfaceView surfaceView() const;  // triangles only; valid while the mesh is unchanged
  Eigen::AlignedBox3d bounds() const;
  /// Scale coordinates to metres and set unitToMetre = 1.
  void convertToMetres();
  /// Remove points used by no element, renumbering elements; returns the old index of each kept point.
  std::vector<int> compact();
};

/// Boundary (outer) triangles of a tet mesh, oriented outward, with the tet label as triangle label.
/// Faces shared by two tets of different labels are included when `includeInterfaces` is true.
std::vector<std::array<int, 3>> boundaryTriangles(const Mesh& volume, bool includeInterfaces,
                                                  std::vector<int>* labels = nullptr);

/// Length units accepted by importers: "m", "dm", "cm", "mm". Returns metres per unit;
/// throws MeshError naming the accepted units otherwise.
double metresPerUnit(const std::string& unit);

/// Whether a mesh read in `unit` that measures `sizeMetres` across (its largest extent) has an organ's size (10 to 1000
/// mm), and if not, the units that would give it one, with its size in each (metres), the most common first (mm, m, cm,
/// dm): a file's numbers alone may fit two (23 units: a 23 mm patch, or 23 cm), so every one is said.
struct OrganSize {
  bool organSized = true;
  std::vector<std::pair<std::string, double>> likely;
  /// "mm (23 mm across) or cm (233 mm across)"; empty when none.
  std::string likelyText() const;
};
OrganSize checkOrganSize(double sizeMetres, const std::string& unit);

}  // namespace rehearse::simcore
