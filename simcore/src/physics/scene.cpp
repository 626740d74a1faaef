#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/input_ranges.hpp>
#include <rehearse/text_input.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

using nlohmann::json;

namespace rehearse::simcore {

LinearSolverKind linearSolverFromString(const std::string& name) {
  if (name == "cholmod") return LinearSolverKind::Cholmod;
  if (name == "cg") return LinearSolverKind::ConjugateGradient;
  if (name == "dense") return LinearSolverKind::Dense;
  throw MeshError("The solver kind must be cholmod, cg or dense, not '" + name + "'.");
}

bool simplicialFactorFromString(const std::string& name) {
  if (name == "supernodal") return false;
  if (name == "simplicial") return true;
  throw MeshError("The factor must be supernodal or simplicial, not '" + name + "'.");
}

AttachmentMode attachmentModeFromString(const std::string& name) {
  if (name == "projection") return AttachmentMode::Projection;
  if (name == "lagrange") return AttachmentMode::Lagrange;
  throw MeshError("The attachment mode must be projection or lagrange, not '" + name + "'.");
}

const std::vector<ComponentDecl>& sceneComponents() {
  static const std::vector<ComponentDecl> decls = {
      {"mesh",
       "The organ's volume mesh (a surface is tetrahedralised).",
       {{"file", "string", "", "", "mesh file, relative to the scene"},
        {"unit", "string", "\"m\"", "", "length unit of the file: m, dm, cm or mm"}}},
      {"material",
       "Material of the elements with one label (label -1: every label without its own material).",
       {{"label", "integer", "-1", "", "element label"},
        {"model", "string", "\"corotational\"", "", "linear, corotational, stvk, neohookean or neohookean-split"},
        {"young", "number", "3000", "Pa", "Young's modulus"},
        {"poisson", "number", "0.3", "", "Poisson's ratio, in [0, 0.5)"},
        {"density", "number", "1000", "kg/m^3", "mass density"},
        {"tear_strain", "number", "0", "",
         "engineering strain at which it tears (largest principal stretch - 1); 0: it does not tear"}},
       true},
      {"attachments",
       "Nodes held in place (the ligaments, q(j) = 1).",
       {{"nodes", "integers", "", "", "0-based node indices in file order"},
        {"mode", "string", "\"projection\"", "",
         "projection (fixed dofs removed) or lagrange (multipliers, Gauss-Seidel)"}}},
      {"gravity",
       "Gravity; without this component there is none.",
       {{"vector", "vector3", "[0, -9.81, 0]", "m/s^2", "acceleration"}}},
      {"damping",
       "Rayleigh damping D = alpha M + beta K; without this component there is none.",
       {{"rayleigh_mass", "number", "0.1", "1/s", "alpha"}, {"rayleigh_stiffness", "number", "0.1", "s", "beta"}}},
      {"implicit_euler",
       "Implicit (backward) Euler time stepping with Newton iterations.",
       {{"dt", "number", "0.01", "s", "time step"},
        {"steps", "integer", "100", "", "number of steps"},
        {"newton_iterations", "integer", "10", "", "Newton iterations per step at most"},
        {"tolerance", "number", "1e-6", "", "relative residual"},
        {"strict", "boolean", "false", "",
         "a step that does not converge after the retries is rolled back (failed) instead of kept as the best attempt "
         "(inexact)"},
        {"inversion_guard", "boolean", "true", "",
         "linear, corotational and neohookean-split elements are kept from inverting (the nodes of an element that "
         "would go below 1 % of its volume stop)"},
        {"volume_barrier", "number", "0.3", "",
         "corotational elements crushed below this volume ratio J resist ever more (an energy growing without bound as "
         "J -> 0), so a crushed element's equilibrium stays open; 0 turns it off"}}},
      {"static",
       "Static equilibrium instead of time stepping (registration).",
       {{"newton_iterations", "integer", "30", "", "Newton iterations at most"},
        {"tolerance", "number", "1e-6", "", "relative residual"}}},
      {"embedded",
       "An inner structure given as a surface (vessels, tumour), embedded by barycentric mapping; its wall stiffness "
       "acts on the organ.",
       {{"file", "string", "", "", "surface file, relative to the scene"},
        {"unit", "string", "\"m\"", "", "length unit of the file: m, dm, cm or mm"},
        {"young", "number", "620e3", "Pa", "Young's modulus of the wall"},
        {"thickness", "number", "0.001", "m", "wall thickness"},
        {"name", "string", "\"inner\"", "", "name used in the output files"}},
       true},
      {"model",
       "The deformable model: the tetrahedral FEM (every law, cuts and tears), Cotin's precomputed linear "
       "elasticity (quasi-static, exact for the linear law, tool forces at haptic rate; it cannot cut, tear, clip or "
       "burn), their hybrid model (a FEM region where the instruments work, the rest's precomputed responses; "
       "quasi-static and linear; it cuts) or the parameterized mesh with free-form deformation (geometric, Hertz's "
       "force; it cannot cut, tear, clip or burn).",
       {{"kind", "string", "\"fem\"", "", "fem, precomputed, hybrid or ffd"}}},
      {"solver",
       "Linear solver and how Newton reuses its factorisation.",
       {{"kind", "string", "\"cholmod\"", "", "cholmod, cg or dense"},
        {"method", "string", "\"chord\"", "",
         "chord (the interactive default: converged every step; exact with the cg and dense solvers), exact, "
         "lagged-pcg, linearised or newton-krylov (all but exact reuse a cholmod factorisation)"},
        {"factor", "string", "\"supernodal\"", "",
         "cholmod factor: supernodal (fastest) or simplicial (re-factorising allocates nothing; about 1.8x slower)"},
        {"linearised_tolerance", "number", "0.01", "",
         "the linearised method's tolerance on the relative residual of the nonlinear equations (steps above it are "
         "inexact)"},
        {"estimate_error", "boolean", "true", "",
         "each step estimates its distance from the converged answer in mm and N (one more solve with its factor: "
         "about 2-3 ms a step on a 9k-element liver); false saves that time"},
        {"accuracy_mm", "number", "0", "mm",
         "the accuracy a step is asked for: it ends once its largest node is estimated within this of the converged "
         "answer and the tool force within accuracy_force_percent (or the residual is under the tolerance); 0: the "
         "relative residual alone"},
        {"accuracy_force_percent", "number", "0.5", "%", "with accuracy_mm: the tool force's share asked (at least 1 mN)"}}},
  };
  return decls;
}

std::string describeSceneComponents() {
  std::string out;
  for (const auto& c : sceneComponents()) {
    out += c.type + (c.repeatable ? " (repeatable)" : "") + ": " + c.help + "\n";
    for (const auto& p : c.parameters)
      out += "  " + p.name + " (" + p.kind + (p.unit.empty() ? "" : ", " + p.unit) + ", " +
             (p.defaultValue.empty() ? std::string("required") : "default " + p.defaultValue) + "): " + p.help + "\n";
  }
  return out;
}

namespace {
[[noreturn]] void fail(const std::string& msg) { throw MeshError("Scene: " + msg); }

// The value of a declared parameter: from the component, else its declared default.
// A name parsed by one of the shared parsers, its sentence prefixed as the scene's other errors are.
template <typename F>
auto named(F f) {
  try {
    return f();
  } catch (const MeshError& e) {
    fail(e.what());
  }
}

// A whole number in [lo, hi] (a float such as 1e12 or 2.5, or a number beyond the range, is refused, not truncated).
long wholeNumber(const json& v, const std::string& what, long lo, long hi) {
  if (!v.is_number()) fail(what + " must be a whole number.");
  const double d = v.get<double>();
  if (!(d >= static_cast<double>(lo) && d <= static_cast<double>(hi)) || d != std::floor(d))
    fail(what + " must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], not " +
         v.dump() + ".");
  return static_cast<long>(d);
}

json value(const json& component, const ComponentDecl& decl, const std::string& name) {
  for (const auto& p : decl.parameters)
    if (p.name == name) {
      if (component.contains(name)) return component[name];
      if (p.defaultValue.empty()) fail("component '" + decl.type + "' needs the parameter '" + name + "' (" + p.help + ").");
      return json::parse(p.defaultValue);
    }
  fail("internal: undeclared parameter " + name);
}
}  // namespace

Scene parseScene(const std::string& text, const std::string& baseDir) {
  if (const std::string why = jsonTextProblem(text, "the scene"); !why.empty()) fail(why + ".");
  json root;
  try {
    root = json::parse(text);
  } catch (const std::exception&) {
    fail("the file is not valid JSON.");
  }
  if (!root.is_object() || !root.contains("components") || !root["components"].is_array())
    fail("it needs a \"components\" array; see 'rehearse simulate --list-components'.");
  for (const auto& [k, v] : root.items())
    if (k != "components") fail("unknown top-level key '" + k + "'.");
  Scene s;
  s.settings.gravity.setZero();  // only what is declared exists
  s.settings.rayleighMass = 0;
  s.settings.rayleighStiffness = 0;
  std::set<std::string> seen;
  bool haveMesh = false;
  bool explicitBarrier = false;  // implicit_euler names volume_barrier
  for (const auto& c : root["components"]) {
    if (!c.is_object() || !c.contains("type") || !c["type"].is_string()) fail("every component needs a \"type\".");
    const std::string type = c["type"].get<std::string>();
    const ComponentDecl* decl = nullptr;
    for (const auto& d : sceneComponents())
      if (d.type == type) decl = &d;
    if (!decl) fail("unknown component '" + type + "'; see 'rehearse simulate --list-components'.");
    if (!decl->repeatable && !seen.insert(type).second) fail("component '" + type + "' appears twice.");
    for (const auto& [k, v] : c.items()) {
      if (k == "type") continue;
      bool known = false;
      for (const auto& p : decl->parameters) known |= p.name == k;
      if (!known) fail("component '" + type + "' has no parameter '" + k + "'.");
    }
    try {
      if (type == "mesh") {
        std::filesystem::path file = value(c, *decl, "file").get<std::string>();
        if (file.is_relative()) file = std::filesystem::path(baseDir) / file;
        s.mesh = loadMesh(file.string(), {value(c, *decl, "unit").get<std::string>()});
        haveMesh = true;
      } else if (type == "material") {
        MaterialParams p{materialModelFromString(value(c, *decl, "model").get<std::string>()),
                         value(c, *decl, "young").get<double>(), value(c, *decl, "poisson").get<double>(),
                         value(c, *decl, "density").get<double>(), value(c, *decl, "tear_strain").get<double>()};
        if (!(p.tearStrain >= 0 && p.tearStrain <= 10)) fail("'tear_strain' must be in [0, 10] (0: it does not tear).");
        const int label = static_cast<int>(wholeNumber(value(c, *decl, "label"), "a material's label", -1, 1000000));
        if (label < 0) s.defaultMaterial = p;
        else s.materials[label] = p;
      } else if (type == "attachments") {
        s.fixedNodes.clear();
        for (const auto& n : value(c, *decl, "nodes"))
          s.fixedNodes.push_back(static_cast<int>(wholeNumber(n, "an attachment's node index", 0, 1L << 30)));
        s.settings.attachments = named([&] { return attachmentModeFromString(value(c, *decl, "mode").get<std::string>()); });
      } else if (type == "embedded") {
        std::filesystem::path file = value(c, *decl, "file").get<std::string>();
        if (file.is_relative()) file = std::filesystem::path(baseDir) / file;
        EmbeddedSurface e;
        e.surface = loadMesh(file.string(), {value(c, *decl, "unit").get<std::string>()});
        if (e.surface.triangles.empty()) fail("the embedded surface " + file.string() + " has no triangles.");
        e.young = value(c, *decl, "young").get<double>();
        e.thickness = value(c, *decl, "thickness").get<double>();
        e.name = value(c, *decl, "name").get<std::string>();
        s.embedded.push_back(std::move(e));
      } else if (type == "gravity") {
        const auto g = value(c, *decl, "vector").get<std::vector<double>>();
        if (g.size() != 3) fail("gravity 'vector' needs three numbers.");
        s.settings.gravity = Eigen::Vector3d(g[0], g[1], g[2]);
      } else if (type == "damping") {
        s.settings.rayleighMass = value(c, *decl, "rayleigh_mass").get<double>();
        s.settings.rayleighStiffness = value(c, *decl, "rayleigh_stiffness").get<double>();
      } else if (type == "implicit_euler") {
        s.settings.timeStep = value(c, *decl, "dt").get<double>();
        s.steps = wholeNumber(value(c, *decl, "steps"), "implicit_euler's steps", 1, InputRanges::maxSteps);
        s.settings.maxNewtonIterations = static_cast<int>(
            wholeNumber(value(c, *decl, "newton_iterations"), "newton_iterations", 1, InputRanges::maxNewtonIterations));
        s.settings.tolerance = value(c, *decl, "tolerance").get<double>();
        s.settings.strict = value(c, *decl, "strict").get<bool>();
        s.settings.inversionGuard = value(c, *decl, "inversion_guard").get<bool>();
        s.settings.volumeBarrier = value(c, *decl, "volume_barrier").get<double>();
        explicitBarrier = c.contains("volume_barrier");
        if (!(s.settings.volumeBarrier >= 0 && s.settings.volumeBarrier < 1))
          fail("implicit_euler's volume_barrier is a volume ratio from 0 (off) up to, not including, 1.");
        if (!(s.settings.timeStep > 0) || s.steps < 1) fail("implicit_euler needs dt > 0 and steps >= 1.");
      } else if (type == "static") {
        s.staticSolve = true;
        s.settings.maxNewtonIterations = static_cast<int>(
            wholeNumber(value(c, *decl, "newton_iterations"), "newton_iterations", 1, InputRanges::maxNewtonIterations));
        s.settings.tolerance = value(c, *decl, "tolerance").get<double>();
      } else if (type == "model") {
        s.bodyModel = value(c, *decl, "kind").get<std::string>();
        if (s.bodyModel != "fem" && s.bodyModel != "precomputed" && s.bodyModel != "hybrid" && s.bodyModel != "ffd")
          fail("the model's kind is \"" + s.bodyModel + "\": fem, precomputed, hybrid or ffd.");
      } else if (type == "solver") {
        s.settings.solver = named([&] { return linearSolverFromString(value(c, *decl, "kind").get<std::string>()); });
        s.methodNamed = c.contains("method");
        s.settings.method =
            s.methodNamed
                ? named([&] { return newtonMethodFromString(value(c, *decl, "method").get<std::string>()); })
                : defaultMethodFor(s.settings.solver);
        s.settings.simplicialFactor = named([&] { return simplicialFactorFromString(value(c, *decl, "factor").get<std::string>()); });
        s.settings.linearisedTolerance = value(c, *decl, "linearised_tolerance").get<double>();
        if (!(s.settings.linearisedTolerance > 0)) fail("the solver's linearised_tolerance must be positive.");
        s.settings.estimateError = value(c, *decl, "estimate_error").get<bool>();
        s.settings.accuracyPosition = 1e-3 * value(c, *decl, "accuracy_mm").get<double>();
        s.settings.accuracyForce = 1e-2 * value(c, *decl, "accuracy_force_percent").get<double>();
      }
    } catch (const json::exception&) {
      fail("a parameter of component '" + type + "' has the wrong kind of value; see 'rehearse simulate --list-components'.");
    }
    s.components.push_back(type);
  }
  if (!haveMesh) fail("it declares no 'mesh' component.");
  for (int n : s.fixedNodes)
    if (s.mesh.isVolume() && static_cast<std::size_t>(n) >= s.mesh.points.size())
      fail("an attachment names node " + std::to_string(n) + ", which the mesh (" + std::to_string(s.mesh.points.size()) +
           " nodes) has not.");
  if (seen.count("implicit_euler") && seen.count("static")) fail("declare either 'implicit_euler' or 'static', not both.");
  // The ranges every input path holds (input_ranges.hpp): inside the old ones a run could be set never to end.
  if (const std::string why = settingsProblem(s.settings); !why.empty()) fail(why + ".");
  if (const std::string why = materialRangeProblem(s.defaultMaterial, "the default material"); !why.empty())
    fail(why + ".");
  for (const auto& [label, m] : s.materials)
    if (const std::string why = materialRangeProblem(m, "the material of label " + std::to_string(label)); !why.empty())
      fail(why + ".");
  // The volume barrier is the corotational law's (Lame::barrier): asked for in a scene whose every law is another, it
  // could not be honoured (refused, not dropped). Unasked, its default stands for whatever law there is.
  if (explicitBarrier && s.settings.volumeBarrier > 0) {
    bool corotational = s.defaultMaterial.model == MaterialModel::Corotational;
    for (const auto& [label, m] : s.materials) corotational = corotational || m.model == MaterialModel::Corotational;
    if (!corotational)
      fail("implicit_euler's volume_barrier acts on the corotational law only, and no material here is corotational: "
           "set it to 0 or use the corotational law.");
  }
  if (seen.count("implicit_euler"))
    if (const std::string why = runLengthProblem(static_cast<double>(s.steps), s.settings.timeStep); !why.empty())
      fail(why + ".");
  return s;
}

Scene loadScene(const std::string& path) {
  std::string text, why;
  if (!readTextInput(path, text, why)) throw MeshError("The scene file " + why + ".");
  return parseScene(text, std::filesystem::path(path).parent_path().string());
}

}  // namespace rehearse::simcore
