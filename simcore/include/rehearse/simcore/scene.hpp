#pragma once
// JSON scenes: a scene declares the components it uses, and only those are built. Each component
// declares its parameters once (name, default, SI unit, help); the loader, the command line's
// component list and (later) the property panel all read that declaration. Unknown components or
// parameters are refused with a message naming them.
//
//   {"components": [
//     {"type": "mesh", "file": "liver.msh", "unit": "cm"},
//     {"type": "material", "label": 1, "model": "corotational", "young": 3000, "poisson": 0.3, "density": 1},
//     {"type": "attachments", "nodes": [3, 39, 64]},
//     {"type": "gravity", "vector": [0, -9.81, 0]},
//     {"type": "damping", "rayleigh_mass": 0.1, "rayleigh_stiffness": 0.1},
//     {"type": "implicit_euler", "dt": 0.02, "steps": 100},
//     {"type": "solver", "kind": "cholmod", "method": "exact"},
//     {"type": "embedded", "file": "vessels.obj", "unit": "mm", "young": 620e3, "thickness": 0.001}]}
#include <rehearse/simcore/integrator.hpp>

#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct ParameterDecl {
  std::string name;
  std::string kind;          ///< "number", "integer", "string", "vector3", "integers"
  std::string defaultValue;  ///< as JSON text; empty = required
  std::string unit;          ///< SI unit ("" when none)
  std::string help;
};

struct ComponentDecl {
  std::string type;
  std::string help;
  std::vector<ParameterDecl> parameters;
  bool repeatable = false;  ///< may appear more than once (materials by label)
};

/// The names of solver settings, parsed in one place for scenes, the command line and the panels. Each
/// throws MeshError naming the accepted values.
LinearSolverKind linearSolverFromString(const std::string& name);  ///< "cholmod", "cg", "dense"
bool simplicialFactorFromString(const std::string& name);          ///< "supernodal" (false), "simplicial" (true)
AttachmentMode attachmentModeFromString(const std::string& name);  ///< "projection", "lagrange"

/// Every component a scene may declare.
const std::vector<ComponentDecl>& sceneComponents();
/// Human-readable list of the components and their parameters (for `rehearse simulate --list-components`).
std::string describeSceneComponents();

/// A loaded scene: what was declared, built.
struct Scene {
  Mesh mesh;
  std::map<int, MaterialParams> materials;
  MaterialParams defaultMaterial;
  std::vector<int> fixedNodes;
  std::vector<EmbeddedSurface> embedded;  ///< inner structures given as surfaces
  SimulationSettings settings = [] {
    SimulationSettings s;
    s.method = kInteractiveMethod;  // a scene or preset without a method runs the interactive default
    return s;
  }();
  bool methodNamed = false;  ///< its solver component named a method (else: defaultMethodFor its solver)
  bool staticSolve = false;
  std::string bodyModel = "fem";  ///< the 'model' component's kind: fem or precomputed (body.hpp: BodyModel)
  long steps = 100;
  std::vector<std::string> components;  ///< the components built, in declaration order
};

/// Reads a scene file; relative mesh paths are relative to the scene file. Throws MeshError with one
/// sentence naming the offending component or parameter.
Scene loadScene(const std::string& path);
Scene parseScene(const std::string& json, const std::string& baseDir);

}  // namespace rehearse::simcore
