// Tetrahedralisation with CGAL Mesh_3 on a labelled implicit domain. Surfaces become a labelling
// function through point-in-surface queries (Side_of_triangle_mesh), so outer and inner closed
// parts (vessels, tumours) are meshed in one conforming mesh with one code path.
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include "cgal_surface.hpp"

#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/make_mesh_3.h>

#include <cstdio>
#include <CGAL/Polygon_mesh_processing/measure.h>

#include <cmath>
#include <map>
#include <memory>
#include <unordered_map>

namespace rehearse::simcore {
namespace {

using K = detail::Kernel;
using MeshDomain = CGAL::Labeled_mesh_domain_3<K>;
using Tr = CGAL::Mesh_triangulation_3<MeshDomain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

Mesh extract(const C3t3& c3t3) {
  Mesh m;
  std::unordered_map<Tr::Vertex_handle, int> index;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    std::array<int, 4> t{};
    for (int k = 0; k < 4; ++k) {
      auto v = c->vertex(k);
      auto [it, inserted] = index.emplace(v, static_cast<int>(m.points.size()));
      if (inserted) {
        const auto& p = v->point().point();
        m.points.emplace_back(p.x(), p.y(), p.z());
      }
      t[k] = it->second;
    }
    m.tets.push_back(t);
    m.tetLabels.push_back(static_cast<int>(c3t3.subdomain_index(c)));
  }
  return m;
}

std::string thousands(long n) {
  char text[32];
  if (n >= 1000000) std::snprintf(text, sizeof text, "%.1f M", static_cast<double>(n) / 1e6);
  else std::snprintf(text, sizeof text, "%ld k", n / 1000);
  return text;
}

Mesh meshOnce(const LabelFunction& label, const Eigen::AlignedBox3d& bounds, const TetrahedraliseOptions& o,
              double size, std::atomic<long>& calls, int pass) {
  const std::atomic<bool>* cancel = o.cancel;
  long queries = 0;
  const std::string refining = "refining the mesh (pass " + std::to_string(pass) + "): ";
  auto f = [&label, &calls, &queries, &o, &refining, cancel](const K::Point_3& p) -> int {
    ++calls;
    // Cancel also during initialisation, which the stop flag does not reach.
    if ((++queries & 1023) == 0 && cancel && cancel->load()) throw Cancelled();
    // Mesh_3 has no progress of its own; its inside/outside queries are the work it does, so say how many.
    if ((queries & 65535) == 0 && o.progress) o.progress(-1, refining + thousands(queries) + " inside/outside queries");
    return label(Eigen::Vector3d(p.x(), p.y(), p.z()));
  };
  const Eigen::Vector3d lo = bounds.min(), hi = bounds.max();
  CGAL::Bbox_3 bbox(lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
  CGAL::Random rng(o.seed);
  MeshDomain domain(std::function<int(const K::Point_3&)>(f), bbox, 1e-5, CGAL::Null_subdomain_index(), &rng);
  namespace P = CGAL::parameters;
  Criteria criteria(P::facet_angle = 25, P::facet_size = size, P::facet_distance = size / 12.0,
                    P::cell_radius_edge_ratio = 2.5, P::cell_size = size);
  CGAL::get_default_random() = CGAL::Random(o.seed);
  std::atomic<bool> stop{false};
  std::atomic<bool>* stopPtr = const_cast<std::atomic<bool>*>(o.cancel ? o.cancel : &stop);
  C3t3 c3t3;
  auto opts = CGAL::parameters::mesh_3_options(CGAL::parameters::pointer_to_stop_atomic_boolean = stopPtr,
                                               CGAL::parameters::maximal_number_of_vertices = kMaxMeshItems / 4);
  if (o.progress) o.progress(-1, refining + "starting");
  c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, CGAL::parameters::no_lloyd(), CGAL::parameters::no_odt(),
                                 CGAL::parameters::no_perturb(), CGAL::parameters::no_exude(), opts);
  if (o.cancel && o.cancel->load()) throw Cancelled();
  if (o.optimise) {
    // Exudation as its own stage (what make_mesh_3 would run last), so it can be reported. time_limit = 0:
    // none. Left unset, CGAL stops exuding after as long as the refinement took, so a busy machine made a
    // different mesh (1 run in 150).
    if (o.progress)
      o.progress(-1, "removing slivers (exudation) from " + std::to_string(c3t3.number_of_cells_in_complex()) + " tetrahedra");
    CGAL::exude_mesh_3(c3t3, CGAL::parameters::time_limit = 0, CGAL::parameters::sliver_bound = 12);
  }
  Mesh m = extract(c3t3);
  repairVolume(m);  // CGAL cells are positively oriented; this only drops (rare) flat cells
  return m;
}

}  // namespace

Mesh tetrahedraliseImplicit(const LabelFunction& label, const Eigen::AlignedBox3d& bounds,
                            const TetrahedraliseOptions& o, double volumeEstimate) {
  if (bounds.isEmpty() || !(bounds.sizes().minCoeff() > 0))
    throw MeshError("The region to mesh is empty; check the surface's size and unit.");
  double size = o.cellSize;
  if (size <= 0) {
    if (o.targetTets < 10 || o.targetTets > kMaxMeshItems)
      throw MeshError("The target element count must be between 10 and " + std::to_string(kMaxMeshItems) + ".");
    // Edge of a regular tet with volume V/N; Mesh_3's cells come out smaller than the size bound,
    // so start larger and correct once from the count actually obtained.
    size = 1.33 * std::cbrt(6.0 * std::sqrt(2.0) * volumeEstimate / static_cast<double>(o.targetTets));
  }
  std::atomic<long> calls{0};
  auto report = [&](double f, const char* stage) {
    if (o.progress) o.progress(f, stage);
  };
  report(0.05, "meshing");
  Mesh m = meshOnce(label, bounds, o, size, calls, 1);
  // The count is not exactly proportional to size^-3 (the surface refines on its own criteria):
  // correct the size up to twice and keep the closest result.
  for (int pass = 0; pass < 2 && o.cellSize <= 0 && !m.tets.empty(); ++pass) {
    const double ratio = static_cast<double>(m.tets.size()) / static_cast<double>(o.targetTets);
    if (ratio > 0.85 && ratio < 1.18) break;
    report(0.35 + 0.3 * pass, "meshing (size corrected)");
    size *= std::cbrt(ratio);
    Mesh next = meshOnce(label, bounds, o, size, calls, pass + 2);
    const double nextRatio = static_cast<double>(next.tets.size()) / static_cast<double>(o.targetTets);
    if (std::abs(std::log(nextRatio)) < std::abs(std::log(ratio))) m = std::move(next);
  }
  report(1.0, "done");
  if (m.tets.empty())
    throw MeshError("Meshing produced no tetrahedra; the element size is too large for this organ (reduce the size or raise the target count).");
  return m;
}

Mesh tetrahedraliseSurface(const Mesh& surface0, const TetrahedraliseOptions& o, std::vector<std::string>* notes) {
  Mesh surface = surface0;
  surface.convertToMetres();
  if (surface.triangles.empty()) throw MeshError("There is no surface to tetrahedralise; load a surface mesh first.");
  if (o.progress) o.progress(0.0, "checking the surface");
  Mesh closedParts;
  SurfaceCheck check = checkSurface(surface, o.allowSelfIntersections, &closedParts);
  if (check.selfIntersections > 0 && notes)
    notes->push_back("The organ surface intersects itself (" + std::to_string(check.selfIntersections) +
                     " triangle pairs); its inside was decided by ray parity, so check the result.");
  if (notes) notes->insert(notes->end(), check.notes.begin(), check.notes.end());
  if (o.outerSurface) {
    Mesh outer;
    outer.points = closedParts.points;
    for (std::size_t t = 0; t < closedParts.triangles.size(); ++t)
      if (closedParts.triangleLabels[t] == check.outerPart) {
        outer.triangles.push_back(closedParts.triangles[t]);
        outer.triangleLabels.push_back(1);
      }
    outer.compact();
    *o.outerSurface = std::move(outer);
  }
  std::vector<int> partLabels = {check.outerPart};
  partLabels.insert(partLabels.end(), check.innerParts.begin(), check.innerParts.end());
  std::vector<std::unique_ptr<detail::SurfaceMesh3>> meshes;
  std::vector<std::unique_ptr<CGAL::Side_of_triangle_mesh<detail::SurfaceMesh3, K>>> sides;
  for (int l : partLabels) {
    meshes.push_back(std::make_unique<detail::SurfaceMesh3>());
    detail::partToSurfaceMesh(closedParts, l, *meshes.back());
    sides.push_back(std::make_unique<CGAL::Side_of_triangle_mesh<detail::SurfaceMesh3, K>>(*meshes.back()));
  }
  // Outer -> 1; inner part i -> i + 2 (the innermost part wins where parts nest).
  LabelFunction label = [&](const Eigen::Vector3d& p) {
    K::Point_3 q(p.x(), p.y(), p.z());
    if ((*sides[0])(q) == CGAL::ON_UNBOUNDED_SIDE) return 0;
    int result = 1;
    for (std::size_t i = 1; i < sides.size(); ++i)
      if ((*sides[i])(q) != CGAL::ON_UNBOUNDED_SIDE) result = static_cast<int>(i) + 1;
    return result;
  };
  Eigen::AlignedBox3d box = closedParts.bounds();
  Eigen::Vector3d pad = 0.02 * box.sizes();
  box.extend(box.min() - pad);
  box.extend(box.max() + pad);
  Mesh volume = tetrahedraliseImplicit(label, box, o, check.outerVolume);
  std::string outerName = surface.labelName(check.outerPart);
  volume.setLabelName(1, outerName.empty() ? "organ" : outerName);
  for (std::size_t i = 1; i < partLabels.size(); ++i) {
    std::string n = surface.labelName(partLabels[i]);
    volume.setLabelName(static_cast<int>(i) + 1, n.empty() ? "inner part " + std::to_string(partLabels[i]) : n);
  }
  return volume;
}

}  // namespace rehearse::simcore
