// Surface checks and repairs with CGAL's Polygon Mesh Processing.
#include <rehearse/simcore/tetrahedralise.hpp>

#include "cgal_surface.hpp"

#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/stitch_borders.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/bbox.h>
#include <CGAL/Side_of_triangle_mesh.h>

#include <map>
#include <set>

namespace PMP = CGAL::Polygon_mesh_processing;

namespace rehearse::simcore {
namespace detail {

bool partToSurfaceMesh(const Mesh& m, int label, SurfaceMesh3& out) {
  std::vector<Point3> points;
  std::vector<std::vector<std::size_t>> polygons;
  std::map<int, std::size_t> remap;
  for (std::size_t i = 0; i < m.triangles.size(); ++i) {
    if (label >= 0 && m.triangleLabels[i] != label) continue;
    std::vector<std::size_t> poly;
    for (int v : m.triangles[i]) {
      auto [it, inserted] = remap.emplace(v, points.size());
      if (inserted) {
        const auto& p = m.points[v];
        points.emplace_back(p.x(), p.y(), p.z());
      }
      poly.push_back(it->second);
    }
    polygons.push_back(std::move(poly));
  }
  if (polygons.empty()) return false;
  PMP::repair_polygon_soup(points, polygons);
  PMP::orient_polygon_soup(points, polygons);
  out.clear();
  PMP::polygon_soup_to_polygon_mesh(points, polygons, out);
  return !out.is_empty();
}

}  // namespace detail

using detail::SurfaceMesh3;

namespace {
// Closes holes whose perimeter is at most this fraction of the part's bounding-box diagonal
// (larger holes are a missing piece of the organ, not a gap in the file).
constexpr double kMaxHolePerimeter = 0.15;

std::size_t closeHoles(SurfaceMesh3& sm, std::size_t* filled) {
  PMP::stitch_borders(sm);
  std::vector<SurfaceMesh3::Halfedge_index> borders;
  PMP::extract_boundary_cycles(sm, std::back_inserter(borders));
  std::size_t remaining = 0;
  const auto box = PMP::bbox(sm);
  const double diagonal = std::sqrt(CGAL::square(box.xmax() - box.xmin()) + CGAL::square(box.ymax() - box.ymin()) +
                                    CGAL::square(box.zmax() - box.zmin()));
  for (auto h : borders) {
    double perimeter = 0;
    for (auto hh : CGAL::halfedges_around_face(h, sm))
      perimeter += std::sqrt(CGAL::squared_distance(sm.point(sm.source(hh)), sm.point(sm.target(hh))));
    if (perimeter <= kMaxHolePerimeter * diagonal) {
      std::vector<SurfaceMesh3::Face_index> faces;
      PMP::triangulate_hole(sm, h, std::back_inserter(faces));
      ++*filled;
    } else {
      ++remaining;
    }
  }
  return remaining;
}
}  // namespace

long countSelfIntersections(const Mesh& surface) {
  SurfaceMesh3 sm;
  if (!detail::partToSurfaceMesh(surface, -1, sm)) return -1;
  std::vector<std::pair<SurfaceMesh3::Face_index, SurfaceMesh3::Face_index>> pairs;
  PMP::self_intersections(sm, std::back_inserter(pairs));
  return static_cast<long>(pairs.size());
}

SurfaceCheck checkSurface(const Mesh& surface, bool allowSelfIntersections, Mesh* repaired) {
  SurfaceCheck result;
  std::set<int> labels(surface.triangleLabels.begin(), surface.triangleLabels.end());
  struct Part {
    int label;
    SurfaceMesh3 mesh;
    double volume;
  };
  std::vector<Part> closed;
  for (int label : labels) {
    Part p{label, {}, 0};
    std::string name = surface.labelName(label);
    std::string partName = name.empty() ? "part " + std::to_string(label) : "part '" + name + "'";
    if (!detail::partToSurfaceMesh(surface, label, p.mesh)) {
      result.notes.push_back("The " + partName + " has no usable triangles and was ignored.");
      continue;
    }
    if (!CGAL::is_closed(p.mesh)) {
      std::size_t filled = 0;
      std::size_t remaining = closeHoles(p.mesh, &filled);
      if (remaining > 0 || !CGAL::is_closed(p.mesh)) {
        result.notes.push_back("The " + partName + " is not closed (" + std::to_string(remaining) +
                               " large holes) and was left out of the volume.");
        continue;
      }
      result.notes.push_back("The " + partName + " had " + std::to_string(filled) + " small holes, which were closed.");
    }
    if (!PMP::is_outward_oriented(p.mesh)) PMP::reverse_face_orientations(p.mesh);
    p.volume = PMP::volume(p.mesh);
    closed.push_back(std::move(p));
  }
  if (closed.empty())
    throw MeshError("The surface has no closed part, so it has no inside to fill with tetrahedra; close its holes in a mesh editor and load it again.");
  std::size_t outer = 0;
  for (std::size_t i = 1; i < closed.size(); ++i)
    if (closed[i].volume > closed[outer].volume) outer = i;
  result.outerPart = closed[outer].label;
  result.outerVolume = closed[outer].volume;
  std::vector<std::pair<SurfaceMesh3::Face_index, SurfaceMesh3::Face_index>> pairs;
  PMP::self_intersections(closed[outer].mesh, std::back_inserter(pairs));
  result.selfIntersections = static_cast<long>(pairs.size());
  if (!pairs.empty() && !allowSelfIntersections)
    throw MeshError("The organ surface intersects itself (" + std::to_string(pairs.size()) +
                    " triangle pairs), so its inside is ambiguous; repair it in a mesh editor (for example MeshLab's "
                    "'Select Self Intersecting Faces') and load it again.");
  CGAL::Side_of_triangle_mesh<SurfaceMesh3, detail::Kernel> inside(closed[outer].mesh);
  for (std::size_t i = 0; i < closed.size(); ++i) {
    if (i == outer) continue;
    bool allInside = true;
    for (auto v : closed[i].mesh.vertices())
      if (inside(closed[i].mesh.point(v)) != CGAL::ON_BOUNDED_SIDE) {
        allInside = false;
        break;
      }
    std::string name = surface.labelName(closed[i].label);
    if (allInside) result.innerParts.push_back(closed[i].label);
    else result.notes.push_back("The part " + (name.empty() ? std::to_string(closed[i].label) : "'" + name + "'") +
                                " lies (partly) outside the organ and was left out of the volume.");
  }
  if (repaired) {
    *repaired = Mesh{};
    repaired->labelNames = surface.labelNames;
    auto append = [&](const Part& p) {
      std::map<SurfaceMesh3::Vertex_index, int> index;
      for (auto v : p.mesh.vertices()) {
        index[v] = static_cast<int>(repaired->points.size());
        const auto& q = p.mesh.point(v);
        repaired->points.emplace_back(q.x(), q.y(), q.z());
      }
      for (auto f : p.mesh.faces()) {
        std::array<int, 3> t{};
        int k = 0;
        for (auto v : CGAL::vertices_around_face(p.mesh.halfedge(f), p.mesh))
          if (k < 3) t[k++] = index[v];
        repaired->triangles.push_back(t);
        repaired->triangleLabels.push_back(p.label);
      }
    };
    append(closed[outer]);
    for (int l : result.innerParts)
      for (const auto& p : closed)
        if (p.label == l) append(p);
  }
  return result;
}

}  // namespace rehearse::simcore
