// rehearse phantom | mesh | info: the built-in case as files, a surface tetrahedralised, a mesh or a case described.
#include "support.hpp"

#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "rehearse/app/casefile.hpp"
#include "rehearse/app/casefolder.hpp"
#include "rehearse/app/elasticfit.hpp"
#include "rehearse/app/appearancestep.hpp"
#include "rehearse/app/gesture.hpp"
#include "rehearse/app/recording.hpp"
#include "rehearse/app/review.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/simcore/words.hpp>
#include <rehearse/imaging/appearance.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/registration.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <rehearse/simcore/labelimage.hpp>

#include <nlohmann/json.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <unistd.h>

namespace rehearse::app::cli {

int cmdPhantom(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, phantomCommand());
  if (!o.count("out")) throw UsageError("phantom needs --out DIR (or --out CASE.rehearse)");
  phantom::PhantomOptions po;
  if (o.count("tets")) po.targetTets = parseCount(o["tets"], "--tets", 100, 2'000'000);
  if (o.count("seed")) po.seed = static_cast<unsigned>(parseCount(o["seed"], "--seed", 0, 1'000'000));
  auto t0 = std::chrono::steady_clock::now();
  const auto c = phantom::makePhantom(po);
  // CASE.rehearse: one case file, as the GUI saves it (and opens: `rehearse open CASE.rehearse`); else a folder.
  if (std::filesystem::path(o["out"]).extension() == std::string(".") + kCaseSuffix)
    saveCaseFile(caseFromPhantom(c), o["out"]);
  else
    writeCaseDirectory(caseFromPhantom(c), o["out"]);
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf(
      "phantom written to %s: %zu nodes, %zu tets, %zu surface triangles, %zu attachment nodes, frame %dx%d (%.2f s)\n",
      o["out"].c_str(), c.volume.points.size(), c.volume.tets.size(), c.surface.size(), c.attachments.size(),
      c.frame.cols, c.frame.rows, s);
  return 0;
}

int cmdMesh(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, meshCommand());
  if (!o.count("in") || !o.count("out"))
    throw UsageError("mesh needs --in SURFACE|LABELS and --out VOLUME.msh|.vtk|.vtu");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".msh" && ext != ".vtk" && ext != ".vtu" && ext != ".mesh")
    throw UsageError("--out must end in .msh, .vtk, .vtu or .mesh");
  const bool labelImage = simcore::isLabelImagePath(o["in"]);
  for (const char* opt : {"labels", "label", "ras"})
    if (!labelImage && o.count(opt))
      throw UsageError(std::string("--") + opt + " applies to a label image (.nrrd, .nii.gz, .mha, .inr), not to " +
                       std::filesystem::path(o["in"]).filename().string());
  if (labelImage && (o.count("unit") || o.count("allow-self-intersections")))
    throw UsageError("--unit and --allow-self-intersections apply to surfaces; a label image carries its own spacing");
  simcore::TetrahedraliseOptions to;
  if (o.count("target-tets")) to.targetTets = parseCount(o["target-tets"], "--target-tets", 10, 5'000'000);
  if (o.count("size")) to.cellSize = parseNumber(o["size"], "--size") * 1e-3;
  to.allowSelfIntersections = o.count("allow-self-intersections") > 0;
  if (isatty(fileno(stderr)))
    to.progress = [](double f, const std::string& stage) {
      if (f < 0)
        std::fprintf(stderr, "\r     %-64s", stage.c_str());  // a stage of unknown length: its counts
      else
        std::fprintf(stderr, "\r%3.0f%% %-64s", 100 * f, stage.c_str());
    };
  std::vector<std::string> notes;
  simcore::Mesh volume;
  auto t0 = std::chrono::steady_clock::now();
  if (labelImage) {
    // A segmentation: each label a part, in the image's frame (LPS, or RAS on request).
    const simcore::LabelImage image = simcore::readLabelImage(o["in"], o.count("labels") ? o["labels"] : std::string());
    notes = image.notes;
    simcore::LabelMeshOptions lo;
    lo.tetrahedralise = to;
    lo.ras = o.count("ras") > 0;
    if (o.count("label")) {
      std::stringstream list(o["label"]);
      for (std::string part; std::getline(list, part, ',');)
        lo.only.push_back(static_cast<int>(parseCount(part, "--label", 1, 2'147'483'647)));
    }
    volume = simcore::meshLabelImage(image, lo, &notes);
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (isatty(fileno(stderr))) std::fprintf(stderr, "\r%50s\r", "");
    simcore::saveMesh(volume, o["out"], o.count("ascii") > 0);
    std::printf("label image: %s, %ld x %ld x %ld voxels of %.4g x %.4g x %.4g mm\n", image.format.c_str(),
                image.size[0], image.size[1], image.size[2], image.spacing.x() * 1e3, image.spacing.y() * 1e3,
                image.spacing.z() * 1e3);
    for (const auto& n : notes) std::printf("note: %s\n", n.c_str());
    std::printf("%s", simcore::formatQuality(simcore::computeQuality(volume)).c_str());
    std::printf("meshing time: %.3f s\nwritten: %s\n", s, o["out"].c_str());
    // A part that got no element is not in the written mesh: said, and exit 4 (the mesh is not the segmentation).
    const std::vector<int> missing = simcore::unmeshedLabels(image, lo, volume);
    for (int l : missing)
      std::fprintf(stderr,
                   "%s is thinner than the elements and got none; it is not in %s. Mesh finer (--size or "
                   "--target-tets).\n",
                   simcore::describeLabel(image, l).c_str(), o["out"].c_str());
    return missing.empty() ? 0 : 4;
  }
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  auto input = simcore::loadMesh(o["in"], lo, &notes);
  if (input.isVolume()) {
    volume = std::move(input);
    volume.triangles.clear();
    volume.triangleLabels.clear();
    notes.push_back("The input is already a volume mesh; it was converted, not re-meshed.");
  } else {
    volume = simcore::tetrahedraliseSurface(input, to, &notes);
  }
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (isatty(fileno(stderr))) std::fprintf(stderr, "\r%50s\r", "");
  simcore::saveMesh(volume, o["out"], o.count("ascii") > 0);
  for (const auto& n : notes) std::fprintf(stderr, "note: %s\n", n.c_str());
  std::printf("%s", simcore::formatQuality(simcore::computeQuality(volume)).c_str());
  std::printf("meshing time: %.3f s\nwritten: %s\n", s, o["out"].c_str());
  return 0;
}

namespace {
// `info` on a case (a .rehearse file the window saved, or a case folder): what it holds, step by step, then its organ's
// counts and quality as for a mesh file.
int caseInfo(const std::string& path) {
  std::vector<std::string> notes;
  const Case c = loadCase(path, &notes);
  const bool file = isCaseFile(path);
  std::printf("file: %s\nkind: case (%s)\nname: %s\n", path.c_str(),
              file ? "a case file, as the window saves it" : "a case folder", c.name.c_str());
  const simcore::Mesh& volume = c.organ->volume;
  if (c.organ->empty()) {
    std::printf("organ: none (step 1 not done)\n");
  } else {
    std::printf("organ: %zu nodes, %zu tetrahedra%s%s\n", volume.points.size(), volume.tets.size(),
                c.organ->source.empty() ? "" : ", imported from ", c.organ->source.c_str());
    std::printf("attachments: %s\n", simcore::quantity(c.attachments.size(), "node", "nodes").c_str());
  }
  if (c.frame.empty()) std::printf("frame: none (step 2 not done)\n");
  else std::printf("frame: %d x %d px%s\n", c.frame.cols, c.frame.rows, c.rawFrame.empty() ? "" : " (undistorted)");
  if (c.camera.width > 0)
    std::printf("camera: fx %.1f, fy %.1f, cx %.1f, cy %.1f px\n", c.camera.fx(), c.camera.fy(), c.camera.cx(), c.camera.cy());
  else
    std::printf("camera: none\n");
  if (c.contour.segments.empty())
    std::printf("contour: none (step 3 not done)\n");
  else
    std::printf("contour: %s, %s\n", simcore::quantity(c.contour.segments.size(), "piece", "pieces").c_str(),
                simcore::quantity(c.contour.pointCount(), "point", "points").c_str());
  std::printf("pose: %s\n", !c.hasPose         ? "none (step 4 not done)"
                            : c.hasFit()       ? "aligned and elastically fitted (step 5)"
                            : c.poseAligned    ? "aligned by hand (step 4)"
                                               : "placed automatically, not aligned (steps 4 and 5 not done)");
  if (c.appearance) {
    std::string second;
    for (const auto& s : c.appearance->sources)
      if (s.used)
        second = " with " + s.name + " beside the scope's light (the scope's alone " +
                 std::to_string(static_cast<int>(std::lround(100 * c.appearance->scopeExplained))) + " %)";
    std::printf("appearance: the model explains %d %% of the organ's shading%s; %s\n",
                imaging::explainedPercent(c.appearance->explained),
                second.c_str(),
                c.appearance->textureOnly ? "texture only (the frame's colours are drawn, not re-shaded)"
                                          : "re-shaded");
  }
  else
    std::printf("appearance: not estimated (step 6 not done)\n");
  if (file) {
    const auto sessions = listRecordings(path);
    long complete = 0;
    for (const auto& r : sessions) complete += r.complete;
    std::printf("recordings: %s, %ld complete\n", simcore::quantity(sessions.size(), "session", "sessions").c_str(),
                complete);
  }
  for (const auto& n : notes) std::printf("note: %s\n", n.c_str());
  if (!c.organ->empty()) std::printf("%s", simcore::formatQuality(simcore::computeQuality(volume)).c_str());
  return 0;
}
}  // namespace

int cmdInfo(const std::vector<std::string>& args) {
  if (args.size() < 3 || args[2].rfind("--", 0) == 0) throw UsageError("info needs a FILE");
  auto o = parseOptions(args, 3, infoCommand());
  if (isCaseFile(args[2]) || std::filesystem::is_directory(args[2])) {
    if (o.count("unit")) throw UsageError("--unit is for mesh files: a case stores its organ in metres");
    return caseInfo(args[2]);
  }
  if (simcore::isLabelImagePath(args[2])) {
    const simcore::LabelImage image = simcore::readLabelImage(args[2]);
    std::printf("file: %s\nkind: label image (%s)\nvoxels: %ld x %ld x %ld of %.4g x %.4g x %.4g mm\n", args[2].c_str(),
                image.format.c_str(), image.size[0], image.size[1], image.size[2], image.spacing.x() * 1e3,
                image.spacing.y() * 1e3, image.spacing.z() * 1e3);
    std::printf("frame: %s\n", image.frame == "LPS" ? "LPS (x to the patient's left, y posterior, z superior)"
                                                    : "the image's own axes (no orientation stored)");
    for (const auto& [label, count] : image.labelCounts()) {
      auto it = image.names.find(label);
      std::printf("label %d%s%s: %ld voxels, %.2f mL\n", label, it != image.names.end() ? " " : "",
                  it != image.names.end() ? it->second.c_str() : "", count,
                  static_cast<double>(count) * image.voxelVolume() * 1e6);
    }
    for (const auto& n : image.notes) std::printf("note: %s\n", n.c_str());
    return 0;
  }
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  std::vector<std::string> notes;
  auto m = simcore::loadMesh(args[2], lo, &notes);
  auto q = simcore::computeQuality(m);
  if (!m.isVolume()) q.selfIntersections = simcore::countSelfIntersections(m);
  std::printf("file: %s\nkind: %s\nunit: %s (coordinates shown in mm)\n", args[2].c_str(),
              m.isVolume() ? "volume" : "surface", lo.unit.c_str());
  std::printf("%s", simcore::formatQuality(q).c_str());
  for (const auto& n : notes) std::printf("repaired on load: %s\n", n.c_str());
  return 0;
}

const Command& phantomCommand() {
  static const Command command{"phantom",
                               "  rehearse phantom --out DIR|CASE.rehearse [--tets N] [--seed S]\n"
                               "                                   write the built-in phantom case as ordinary files, "
                               "or as one case file\n",
                               {{"out", "DIR", "the folder to write the case into (created), or a .rehearse case file"},
                                {"tets", "N", "about this many tetrahedra (default 3,800)"},
                                {"seed", "S", "the random seed of the frame's texture"}},
                               cmdPhantom};
  return command;
}

const Command& meshCommand() {
  static const Command command{
      "mesh",
      "  rehearse mesh --in SURFACE|LABELS --out VOLUME.msh|.vtk|.vtu [--target-tets N] [--size MM]\n"
      "                [--unit m|dm|cm|mm] [--ascii] [--allow-self-intersections]\n"
      "                [--labels TABLE] [--label N,...] [--ras]\n"
      "                                   tetrahedralise a closed surface (inner closed parts become labels) or a\n"
      "                                   segmentation (NRRD, NIfTI, MetaImage or INR label image: each label a "
      "part;\n"
      "                                   exit 4 when a label is too thin to get an element: written without it)\n",
      {{"in", "SURFACE|LABELS",
        "the closed surface (any mesh format below) or label image (.nrrd, .nii.gz, .mha, .inr.gz)"},
       {"out", "VOLUME", ".msh, .vtk or .vtu"},
       {"target-tets", "N", "about this many tetrahedra"},
       {"size", "MM", "the largest element size instead"},
       {"unit", "U", "m, dm, cm or mm: the surface's length unit"},
       {"ascii", "", "write text instead of binary"},
       {"allow-self-intersections", "", "mesh a surface that intersects itself (it is refused otherwise)"},
       {"labels", "TABLE",
        "a colour table naming the labels (3D Slicer .ctbl or ITK-SNAP .txt; one beside the image is used)"},
       {"label", "N,...", "mesh only these labels"},
       {"ras", "", "coordinates in RAS (3D Slicer's world) instead of LPS (ITK, DICOM)"}},
      cmdMesh};
  return command;
}

const Command& infoCommand() {
  static const Command command{
      "info",
      "  rehearse info FILE|CASE [--unit m|dm|cm|mm]\n"
      "                                   node, element and label counts, bounds and quality; of a case (.rehearse\n"
      "                                   or folder) what each step holds and its recordings too\n",
      {{"unit", "U", "m, dm, cm or mm: a mesh file's length unit (a case stores metres)"}},
      cmdInfo};
  return command;
}

}  // namespace rehearse::app::cli
