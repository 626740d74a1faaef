// The geometry image of an organ's surface through CGAL's Surface_mesh_parameterization (a seam cut to a disk,
// the square border by arc length, discrete authalic or conformal map), and CGAL's approximate Hausdorff distance.
#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/words.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/Seam_mesh.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/distance.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Surface_mesh_parameterization/Discrete_authalic_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/Discrete_conformal_map_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/Error_code.h>
#include <CGAL/Surface_mesh_parameterization/Mean_value_coordinates_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/Square_border_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/parameterize.h>

#include <boost/graph/dijkstra_shortest_paths.hpp>
#include <boost/property_map/property_map.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <queue>

namespace rehearse::simcore {
namespace {

using K = CGAL::Simple_cartesian<double>;
using P2 = K::Point_2;
using P3 = K::Point_3;
using SM = CGAL::Surface_mesh<P3>;
using SMV = SM::Vertex_index;
using SME = SM::Edge_index;
namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMP = CGAL::Surface_mesh_parameterization;
using SeamEdges = SM::Property_map<SME, bool>;
using SeamVertices = SM::Property_map<SMV, bool>;
using Seamed = CGAL::Seam_mesh<SM, SeamEdges, SeamVertices>;
using SeamHalfedge = boost::graph_traits<Seamed>::halfedge_descriptor;
using SeamVertex = boost::graph_traits<Seamed>::vertex_descriptor;

// `repair`: points at the same place merged, the soup oriented (non-manifold points and edges split) as CGAL's
// polygon-soup repair does; without it, the triangles as given (a geometry image's grid, whose border points coincide
// in space without being shared).
bool toSurfaceMesh(const std::vector<Eigen::Vector3d>& points, const std::vector<std::array<int, 3>>& triangles,
                   SM& out, bool repair = true) {
  std::vector<P3> p;
  p.reserve(points.size());
  for (const auto& q : points) p.emplace_back(q.x(), q.y(), q.z());
  std::vector<std::vector<std::size_t>> polygons;
  polygons.reserve(triangles.size());
  for (const auto& t : triangles) {
    for (int v : t)
      if (v < 0 || static_cast<std::size_t>(v) >= points.size()) return false;
    polygons.push_back(
        {static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]), static_cast<std::size_t>(t[2])});
  }
  if (polygons.empty()) return false;
  if (repair) {
    PMP::repair_polygon_soup(p, polygons);
    PMP::orient_polygon_soup(p, polygons);
  }
  if (!PMP::is_polygon_soup_a_polygon_mesh(polygons)) return false;
  out.clear();
  PMP::polygon_soup_to_polygon_mesh(p, polygons, out);
  return !out.is_empty();
}

Eigen::Vector3d eig(const P3& p) { return {p.x(), p.y(), p.z()}; }

}  // namespace

std::vector<std::array<int, 3>> GeometryImage::triangles() const {
  std::vector<std::array<int, 3>> t;
  if (size < 2) return t;
  t.reserve(static_cast<std::size_t>(2 * (size - 1) * (size - 1)));
  for (int i = 0; i + 1 < size; ++i)
    for (int j = 0; j + 1 < size; ++j) {
      const int a = index(i, j), b = index(i, j + 1), c = index(i + 1, j + 1), d = index(i + 1, j);
      t.push_back({a, b, c});
      t.push_back({a, c, d});
    }
  // Outward as the original surface: the cells' normals against the sampled normals, by majority.
  double agree = 0;
  for (const auto& f : t) {
    const Eigen::Vector3d n =
        (points[static_cast<std::size_t>(f[1])] - points[static_cast<std::size_t>(f[0])])
            .cross(points[static_cast<std::size_t>(f[2])] - points[static_cast<std::size_t>(f[0])]);
    agree += n.dot(normals[static_cast<std::size_t>(f[0])] + normals[static_cast<std::size_t>(f[1])] +
                   normals[static_cast<std::size_t>(f[2])]);
  }
  if (agree < 0)
    for (auto& f : t) std::swap(f[1], f[2]);
  return t;
}

namespace {

struct StretchResult {
  int rounds = 0;
  double before = 0, after = 0;
};

// The seamed surface as arrays for minimiseStretch: its vertices (in space and in the map), its triangles, each free
// vertex's row (-1 on the border), the mean-value weights, the triangles' areas and their squared L2 stretch.
struct StretchProblem {
  // A mean-value weight, one entry per corner and neighbour: w_ij = tan(theta_i / 2) / |x_i - x_j|.
  struct Entry {
    int i, j;
    double w;
  };
  std::map<SeamVertex, int> id;
  std::vector<Eigen::Vector3d> x;
  std::vector<Eigen::Vector2d> u;
  std::vector<std::array<int, 3>> tri;
  std::vector<int> unknown;  // free vertices' row; -1 on the border
  std::vector<Entry> entries;
  std::vector<double> area3;
  std::vector<double> stretch2;

  int size() const { return static_cast<int>(x.size()); }
  void gather(const Seamed& mesh, const SM& sm, SeamHalfedge border, std::map<SeamVertex, P2>& uv);
  void weigh();
  bool measure(const std::vector<Eigen::Vector2d>& p, double& total);
  bool solve(const std::vector<double>& factor, int m, Eigen::SparseLU<Eigen::SparseMatrix<double>>& lu,
             bool& analysed, std::vector<double>& next, std::vector<Eigen::Vector2d>& candidate) const;
};

// The surface's vertices and triangles through the seam, their map positions from `uv`, and which are free.
void StretchProblem::gather(const Seamed& mesh, const SM& sm, SeamHalfedge border, std::map<SeamVertex, P2>& uv) {
  tri.reserve(sm.number_of_faces());
  for (auto f : sm.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (SeamHalfedge h : CGAL::halfedges_around_face(CGAL::halfedge(f, mesh), mesh)) {
      if (k > 2) break;
      const SeamVertex sv = CGAL::target(h, mesh);
      const auto [it, added] = id.emplace(sv, static_cast<int>(x.size()));
      if (added) {
        x.push_back(eig(sm.point(CGAL::target(h.tmhd, sm))));
        const P2 q = uv[sv];
        u.emplace_back(q.x(), q.y());
      }
      t[static_cast<std::size_t>(k++)] = it->second;
    }
    tri.push_back(t);
  }
  const int n = size();
  unknown.assign(static_cast<std::size_t>(n), -1);
  std::vector<char> fixed(static_cast<std::size_t>(n), 0);
  for (SeamHalfedge h : CGAL::halfedges_around_face(border, mesh)) {
    const auto it = id.find(CGAL::target(h, mesh));
    if (it != id.end()) fixed[static_cast<std::size_t>(it->second)] = 1;
  }
  int m = 0;
  for (int i = 0; i < n; ++i)
    if (!fixed[static_cast<std::size_t>(i)]) unknown[static_cast<std::size_t>(i)] = m++;
}

// The mean-value weights of the free vertices, and the triangles' areas.
void StretchProblem::weigh() {
  entries.reserve(6 * tri.size());
  area3.resize(tri.size());
  for (std::size_t t = 0; t < tri.size(); ++t) {
    const auto& f = tri[t];
    area3[t] = 0.5 * (x[static_cast<std::size_t>(f[1])] - x[static_cast<std::size_t>(f[0])])
                         .cross(x[static_cast<std::size_t>(f[2])] - x[static_cast<std::size_t>(f[0])])
                         .norm();
    for (int c = 0; c < 3; ++c) {
      const int i = f[static_cast<std::size_t>(c)], j = f[static_cast<std::size_t>((c + 1) % 3)],
                k = f[static_cast<std::size_t>((c + 2) % 3)];
      if (unknown[static_cast<std::size_t>(i)] < 0) continue;
      const Eigen::Vector3d a = x[static_cast<std::size_t>(j)] - x[static_cast<std::size_t>(i)],
                            b = x[static_cast<std::size_t>(k)] - x[static_cast<std::size_t>(i)];
      const double la = a.norm(), lb = b.norm();
      if (!(la > 0) || !(lb > 0)) continue;
      const double theta = std::atan2(a.cross(b).norm(), a.dot(b));
      const double half = std::tan(0.5 * theta);
      entries.push_back({i, j, half / la});
      entries.push_back({i, k, half / lb});
    }
  }
  stretch2.resize(tri.size());
}

// The L2 stretch of each triangle (squared) and the surface's, normalised so that a map keeping every area and
// angle has 1; false when a triangle is folded or flat in the plane.
bool StretchProblem::measure(const std::vector<Eigen::Vector2d>& p, double& total) {
  double sum = 0, sumArea3 = 0, sumArea2 = 0;
  int positive = 0, negative = 0;
  for (std::size_t t = 0; t < tri.size(); ++t) {
    const auto& f = tri[t];
    const Eigen::Vector2d &p1 = p[static_cast<std::size_t>(f[0])], &p2 = p[static_cast<std::size_t>(f[1])],
                          &p3 = p[static_cast<std::size_t>(f[2])];
    const Eigen::Vector3d &q1 = x[static_cast<std::size_t>(f[0])], &q2 = x[static_cast<std::size_t>(f[1])],
                          &q3 = x[static_cast<std::size_t>(f[2])];
    if (unknown[static_cast<std::size_t>(f[0])] < 0 && unknown[static_cast<std::size_t>(f[1])] < 0 &&
        unknown[static_cast<std::size_t>(f[2])] < 0) {
      stretch2[t] = 0;  // (three corners on the border: no round moves it)
      continue;
    }
    const double a2 = 0.5 * ((p2.x() - p1.x()) * (p3.y() - p1.y()) - (p3.x() - p1.x()) * (p2.y() - p1.y()));
    (a2 > 0 ? positive : negative) += a2 != 0;
    if (a2 == 0) return false;
    const Eigen::Vector3d ss = (q1 * (p2.y() - p3.y()) + q2 * (p3.y() - p1.y()) + q3 * (p1.y() - p2.y())) / (2 * a2);
    const Eigen::Vector3d st = (q1 * (p3.x() - p2.x()) + q2 * (p1.x() - p3.x()) + q3 * (p2.x() - p1.x())) / (2 * a2);
    stretch2[t] = 0.5 * (ss.squaredNorm() + st.squaredNorm());
    sum += area3[t] * stretch2[t];
    sumArea3 += area3[t];
    sumArea2 += std::abs(a2);
  }
  if (positive > 0 && negative > 0) return false;
  total = std::sqrt(sum / sumArea3 * sumArea2 / sumArea3);
  return std::isfinite(total);
}

// One round: each vertex's divisor `factor` times the square root of its stretch (in `next`), and the map solved
// again with the weights divided by it (in `candidate`). False when the solve fails.
bool StretchProblem::solve(const std::vector<double>& factor, int m, Eigen::SparseLU<Eigen::SparseMatrix<double>>& lu,
                           bool& analysed, std::vector<double>& next, std::vector<Eigen::Vector2d>& candidate) const {
  const int n = size();
  // Each vertex's stretch: its triangles' squared stretch, weighted by their area, rooted.
  std::vector<double> num(static_cast<std::size_t>(n), 0.0), den(static_cast<std::size_t>(n), 0.0);
  for (std::size_t t = 0; t < tri.size(); ++t)
    for (int v : tri[t])
      num[static_cast<std::size_t>(v)] += area3[t] * stretch2[t], den[static_cast<std::size_t>(v)] += area3[t];
  double largest = 0;
  next = factor;
  for (int v = 0; v < n; ++v) {
    const double s = den[static_cast<std::size_t>(v)] > 0
                         ? std::sqrt(num[static_cast<std::size_t>(v)] / den[static_cast<std::size_t>(v)])
                         : 1.0;
    next[static_cast<std::size_t>(v)] *= std::sqrt(s);  // (eta = 1/2, below)
    largest = std::max(largest, next[static_cast<std::size_t>(v)]);
  }
  for (double& f : next) f /= largest;  // (a common scale changes nothing; this keeps them in range)
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(2 * entries.size());
  Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(m, 2);
  for (const Entry& e : entries) {
    const double w = e.w / next[static_cast<std::size_t>(e.j)];
    const int r = unknown[static_cast<std::size_t>(e.i)], c = unknown[static_cast<std::size_t>(e.j)];
    triplets.emplace_back(r, r, w);
    if (c >= 0)
      triplets.emplace_back(r, c, -w);
    else
      rhs.row(r) += w * u[static_cast<std::size_t>(e.j)].transpose();
  }
  Eigen::SparseMatrix<double> a(m, m);
  a.setFromTriplets(triplets.begin(), triplets.end());
  if (!analysed) lu.analyzePattern(a), analysed = true;
  lu.factorize(a);
  if (lu.info() != Eigen::Success) return false;
  const Eigen::MatrixX2d solved = lu.solve(rhs);
  if (lu.info() != Eigen::Success || !solved.allFinite()) return false;
  candidate = u;
  for (int v = 0; v < n; ++v)
    if (unknown[static_cast<std::size_t>(v)] >= 0)
      candidate[static_cast<std::size_t>(v)] = solved.row(unknown[static_cast<std::size_t>(v)]).transpose();
  return true;
}

// Yoshizawa, Belyaev and Seidel's stretch-minimising parameterization ("A fast and simple stretch-minimizing mesh
// parameterization", 2004): from the mean-value map (border fixed on the square), each interior vertex's weights to its
// neighbours are divided by the neighbours' L2 stretch (Sander, Snyder, Gortler and Hoppe 2001: the root mean square of
// the map's singular values, area-weighted over the vertex's triangles) and the map solved again, while the surface's
// L2 stretch falls. A region the map squeezed (high stretch) pulls its neighbours less and opens up. The weights stay
// positive and the border convex, so every round is an embedding (Floater); a round that folds a triangle anyway (round
// off) ends the search with the round before. `uv` is updated in place.
// The divisor is the stretch's square root (their exponent eta = 1/2): with eta = 1 the second round overshoots (the
// stretch rises again after one round on every organ); eta = 1/2 goes on for 2-4 rounds, and the geometry images of
// the four real organs came nearer their surfaces on all four (patient liver 0.66 -> 0.52 %, BodyParts3D liver
// 0.77 -> 0.69 %, scikit-surgery kidney 0.86 -> 0.84 % of their size; BodyParts3D kidney 0.37 %, conformal, either).
StretchResult minimiseStretch(const Seamed& mesh, const SM& sm, SeamHalfedge border, std::map<SeamVertex, P2>& uv,
                              int maxRounds) {
  StretchProblem s;
  s.gather(mesh, sm, border, uv);
  s.weigh();
  StretchResult result;
  if (!s.measure(s.u, result.before)) return result;
  result.after = result.before;
  const int m = *std::max_element(s.unknown.begin(), s.unknown.end()) + 1;
  if (m <= 0) return result;
  std::vector<double> factor(static_cast<std::size_t>(s.size()), 1.0);  // each vertex's weights' divisor so far
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  bool analysed = false;
  for (int round = 1; round <= maxRounds; ++round) {
    std::vector<double> next;
    std::vector<Eigen::Vector2d> candidate;
    if (!s.solve(factor, m, lu, analysed, next, candidate)) break;
    const std::vector<double> kept = s.stretch2;
    double total = 0;
    if (!s.measure(candidate, total) || total >= result.after * (1 - 1e-3)) {
      s.stretch2 = kept;
      break;
    }
    s.u = std::move(candidate);
    factor = std::move(next);
    result.after = total;
    result.rounds = round;
  }
  for (const auto& [sv, i] : s.id)
    uv[sv] = P2(s.u[static_cast<std::size_t>(i)].x(), s.u[static_cast<std::size_t>(i)].y());
  return result;
}

// The two ends of the surface along its principal axis `axisIndex` (0: the shortest, 2: the longest).
std::pair<SMV, SMV> axisEnds(const SM& sm, int axisIndex) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (auto v : sm.vertices()) c += eig(sm.point(v));
  c /= static_cast<double>(sm.number_of_vertices());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (auto v : sm.vertices()) cov += (eig(sm.point(v)) - c) * (eig(sm.point(v)) - c).transpose();
  const Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(axisIndex);
  SMV lo = *sm.vertices().begin(), hi = lo;
  for (auto v : sm.vertices()) {
    const double s = (eig(sm.point(v)) - c).dot(axis);
    if (s < (eig(sm.point(lo)) - c).dot(axis)) lo = v;
    if (s > (eig(sm.point(hi)) - c).dot(axis)) hi = v;
  }
  return {lo, hi};
}

// A branch of the seam from `b` to the seam (`onSeam`) by the shortest path, added to `mesh`; the seam's edge count
// grows by its edges.
void addSeamBranch(const SM& sm, Seamed& mesh, SMV b, std::vector<char>& onSeam, int& seamCount) {
  if (onSeam[b.idx()]) return;
  // Dijkstra from every seam vertex at once; the path from b back to the seam touches it at its end only.
  std::vector<double> dist(sm.number_of_vertices(), std::numeric_limits<double>::infinity());
  std::vector<SMV> from(sm.number_of_vertices());
  using Item = std::pair<double, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  for (auto v : sm.vertices())
    if (onSeam[v.idx()]) dist[v.idx()] = 0, from[v.idx()] = v, queue.push({0.0, v.idx()});
  while (!queue.empty()) {
    const auto [d, i] = queue.top();
    queue.pop();
    if (d > dist[i]) continue;
    const SMV v(i);
    if (v == b) break;
    for (auto h : CGAL::halfedges_around_target(sm.halfedge(v), sm)) {
      const SMV w = CGAL::source(h, sm);
      const double nd = d + std::sqrt(CGAL::squared_distance(sm.point(v), sm.point(w)));
      if (nd < dist[w.idx()]) dist[w.idx()] = nd, from[w.idx()] = v, queue.push({nd, w.idx()});
    }
  }
  if (!std::isfinite(dist[b.idx()])) return;
  for (SMV v = b; !onSeam[v.idx()];) {
    const SMV p = from[v.idx()];
    if (!mesh.add_seam(p, v)) break;
    onSeam[v.idx()] = 1;
    ++seamCount;
    v = p;
  }
}

// The cut surface mapped to the square by `map` (its border by arc length).
SMP::Error_code parameterizeBy(Seamed& mesh, SurfaceMap map, SeamHalfedge border,
                               boost::associative_property_map<std::map<SeamVertex, P2>>& uv) {
  using Border = SMP::Square_border_arc_length_parameterizer_3<Seamed>;
  if (map == SurfaceMap::Authalic)
    return SMP::parameterize(mesh, SMP::Discrete_authalic_parameterizer_3<Seamed, Border>(), border, uv);
  if (map == SurfaceMap::MeanValue || map == SurfaceMap::Stretch)
    return SMP::parameterize(mesh, SMP::Mean_value_coordinates_parameterizer_3<Seamed, Border>(), border, uv);
  return SMP::parameterize(mesh, SMP::Discrete_conformal_map_parameterizer_3<Seamed, Border>(), border, uv);
}

// A parameter triangle, with its corners' positions and normals.
struct ParamTri {
  std::array<Eigen::Vector2d, 3> uv;
  std::array<Eigen::Vector3d, 3> x, n;
};

// The parameter triangles bucketed on a B x B grid over their bounds, for the lookup.
struct ParamGrid {
  std::vector<ParamTri> tris;
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
  int B = 0;
  std::vector<std::vector<int>> buckets;

  int cellOf(double u, double v) const {
    const int cu = std::clamp(static_cast<int>((u - umin) / (umax - umin) * B), 0, B - 1);
    const int cv = std::clamp(static_cast<int>((v - vmin) / (vmax - vmin) * B), 0, B - 1);
    return cv * B + cu;
  }
  // The triangles with their corners, and their bounds in the map.
  void gather(SM& sm, const Seamed& mesh, std::map<SeamVertex, P2>& uvHash) {
    auto vnormals = sm.add_property_map<SMV, K::Vector_3>("v:normal").first;
    PMP::compute_vertex_normals(sm, vnormals);
    tris.reserve(sm.number_of_faces());
    for (auto f : sm.faces()) {
      ParamTri t;
      int k = 0;
      for (SeamHalfedge h : CGAL::halfedges_around_face(CGAL::halfedge(f, mesh), mesh)) {
        if (k > 2) break;
        const P2 q = uvHash[CGAL::target(h, mesh)];
        const SMV v = CGAL::target(h.tmhd, sm);
        t.uv[static_cast<std::size_t>(k)] = {q.x(), q.y()};
        t.x[static_cast<std::size_t>(k)] = eig(sm.point(v));
        t.n[static_cast<std::size_t>(k)] = {vnormals[v].x(), vnormals[v].y(), vnormals[v].z()};
        umin = std::min(umin, q.x()), umax = std::max(umax, q.x()), vmin = std::min(vmin, q.y()),
        vmax = std::max(vmax, q.y());
        ++k;
      }
      tris.push_back(t);
    }
  }
  void bucket(int N) {
    B = std::max(8, N);
    buckets.assign(static_cast<std::size_t>(B * B), {});
    for (std::size_t t = 0; t < tris.size(); ++t) {
      double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
      for (const auto& q : tris[t].uv)
        a0 = std::min(a0, q.x()), a1 = std::max(a1, q.x()), b0 = std::min(b0, q.y()), b1 = std::max(b1, q.y());
      const int c0 = cellOf(a0, b0), c1 = cellOf(a1, b1);
      for (int cv = c0 / B; cv <= c1 / B; ++cv)
        for (int cu = c0 % B; cu <= c1 % B; ++cu)
          buckets[static_cast<std::size_t>(cv * B + cu)].push_back(static_cast<int>(t));
    }
  }
};

Eigen::Vector3d barycentric(const ParamTri& t, const Eigen::Vector2d& p) {
  const Eigen::Vector2d e0 = t.uv[1] - t.uv[0], e1 = t.uv[2] - t.uv[0], d = p - t.uv[0];
  const double det = e0.x() * e1.y() - e0.y() * e1.x();
  if (std::abs(det) < 1e-300) return Eigen::Vector3d(-1, -1, -1);
  const double b1 = (d.x() * e1.y() - d.y() * e1.x()) / det, b2 = (e0.x() * d.y() - e0.y() * d.x()) / det;
  return Eigen::Vector3d(1 - b1 - b2, b1, b2);
}

// The image's N x N points and normals, each interpolated in the triangle of the map that holds it.
void sampleImage(const ParamGrid& g, int N, GeometryImage& gi) {
  gi.points.resize(static_cast<std::size_t>(N * N));
  gi.normals.resize(gi.points.size());
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      const Eigen::Vector2d p(g.umin + (g.umax - g.umin) * j / (N - 1.0), g.vmin + (g.vmax - g.vmin) * i / (N - 1.0));
      int best = -1;
      double bestMin = -1e300;
      Eigen::Vector3d bestW;
      auto consider = [&](int t) {
        const Eigen::Vector3d w = barycentric(g.tris[static_cast<std::size_t>(t)], p);
        const double m = w.minCoeff();
        if (m > bestMin) bestMin = m, best = t, bestW = w;
      };
      for (int t : g.buckets[static_cast<std::size_t>(g.cellOf(p.x(), p.y()))]) consider(t);
      if (bestMin < -1e-6) {  // outside every triangle of its bucket: the nearest of all (clamped weights)
        ++gi.unplaced;
        for (std::size_t t = 0; t < g.tris.size(); ++t) consider(static_cast<int>(t));
      }
      Eigen::Vector3d w = bestW.cwiseMax(0.0);
      w /= w.sum();
      const ParamTri& t = g.tris[static_cast<std::size_t>(best)];
      const std::size_t k = static_cast<std::size_t>(gi.index(i, j));
      gi.points[k] = w[0] * t.x[0] + w[1] * t.x[1] + w[2] * t.x[2];
      const Eigen::Vector3d n = w[0] * t.n[0] + w[1] * t.n[1] + w[2] * t.n[2];
      gi.normals[k] = n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::UnitZ();
    }
}

// The geometry image of a closed genus-0 surface cut along the shortest path between its ends along principal axis
// `axisIndex` (0: the shortest, 2: the longest), with a branch of the seam from each of `branches` to the seam by the
// shortest path (Gu, Gortler and Hoppe's refinement: a cut through a protrusion the map squeezes lets it open up; the
// seam stays a tree, so the cut surface stays a disk), mapped by `map`.
std::optional<GeometryImage> imageAlong(SM sm, int axisIndex, SurfaceMap map, int N, const std::vector<SMV>& branches,
                                        std::string& why) {
  // The seam: the shortest path over the edges between the two ends of the surface along a principal axis.
  const auto [lo, hi] = axisEnds(sm, axisIndex);
  auto predecessor = sm.add_property_map<SMV, SMV>("v:pred").first;
  auto distance = sm.add_property_map<SMV, double>("v:dist").first;
  boost::dijkstra_shortest_paths(sm, lo, boost::predecessor_map(predecessor).distance_map(distance));
  SeamEdges seamEdges = sm.add_property_map<SME, bool>("e:on_seam", false).first;
  SeamVertices seamVertices = sm.add_property_map<SMV, bool>("v:on_seam", false).first;
  Seamed mesh(sm, seamEdges, seamVertices);
  int seamCount = 0;
  for (SMV v = hi; v != lo;) {
    const SMV p = predecessor[v];
    if (p == v) break;  // (connected: not reached)
    if (!mesh.add_seam(p, v)) {
      why = "The seam that cuts the surface to a disk could not be placed (CGAL's Seam_mesh refused an edge).";
      return std::nullopt;
    }
    ++seamCount;
    v = p;
  }
  if (seamCount == 0) {
    why = "The surface has no two distinct ends to cut a seam between.";
    return std::nullopt;
  }
  std::vector<char> onSeam(sm.number_of_vertices(), 0);
  for (SMV v = hi;; v = predecessor[v]) {
    onSeam[v.idx()] = 1;
    if (v == lo || predecessor[v] == v) break;
  }
  for (SMV b : branches) addSeamBranch(sm, mesh, b, onSeam, seamCount);
  const SeamHalfedge border = PMP::longest_border(mesh).first;
  std::map<SeamVertex, P2> uvHash;
  boost::associative_property_map<std::map<SeamVertex, P2>> uv(uvHash);
  const SMP::Error_code err = parameterizeBy(mesh, map, border, uv);
  if (err != SMP::OK) {
    why = std::string("CGAL's surface parameterization failed: ") + SMP::get_error_message(err) + ".";
    return std::nullopt;
  }
  StretchResult stretch;
  if (map == SurfaceMap::Stretch) stretch = minimiseStretch(mesh, sm, border, uvHash, 30);

  // The parameter triangles, with their corners' positions and normals, bucketed on a grid for the lookup.
  ParamGrid grid;
  grid.gather(sm, mesh, uvHash);
  if (!(grid.umax > grid.umin && grid.vmax > grid.vmin)) {
    why = "The surface's parameterization is degenerate (all of it in one point or line).";
    return std::nullopt;
  }
  grid.bucket(N);
  GeometryImage gi;
  gi.size = N;
  gi.seamEdges = seamCount;
  gi.stretchRounds = stretch.rounds;
  gi.stretchBefore = stretch.before;
  gi.stretchAfter = stretch.after;
  sampleImage(grid, N, gi);
  return gi;
}

}  // namespace

std::optional<GeometryImage> makeGeometryImage(const std::vector<Eigen::Vector3d>& points,
                                               const std::vector<std::array<int, 3>>& triangles,
                                               const GeometryImageSettings& settings, std::string& why) {
  if (settings.size < 3 || settings.size > 2049) {
    why = "A geometry image needs between 3 and 2049 grid points a side (asked " + std::to_string(settings.size) + ").";
    return std::nullopt;
  }
  SM sm;
  if (!toSurfaceMesh(points, triangles, sm)) {
    why =
        "The surface is not a triangle mesh a parameterization can use (empty, an index out of range, or edges shared "
        "by more than two triangles).";
    return std::nullopt;
  }
  // The organ is the largest piece (a file's stray pieces, said); slits a non-manifold edge left when the soup was
  // oriented (two lobes of a mesh touching along an edge) and small holes closed by CGAL's hole filling.
  const std::size_t pieces = PMP::keep_largest_connected_components(sm, 1);
  sm.collect_garbage();
  int filled = 0;
  {
    std::vector<SM::Halfedge_index> borders;
    PMP::extract_boundary_cycles(sm, std::back_inserter(borders));
    const auto box = PMP::bbox(sm);
    const double diagonal = std::hypot(box.xmax() - box.xmin(), box.ymax() - box.ymin(), box.zmax() - box.zmin());
    for (auto h : borders) {
      double perimeter = 0;
      for (auto e : CGAL::halfedges_around_face(h, sm))
        perimeter += std::sqrt(CGAL::squared_distance(sm.point(CGAL::source(e, sm)), sm.point(CGAL::target(e, sm))));
      if (perimeter > 0.15 * diagonal) continue;
      std::vector<SM::Face_index> added;
      PMP::triangulate_hole(sm, h, std::back_inserter(added));
      ++filled;
    }
  }
  if (!CGAL::is_closed(sm)) {
    why = "The surface has holes: the geometry image needs a closed organ surface.";
    return std::nullopt;
  }
  const long euler = static_cast<long>(sm.number_of_vertices()) - static_cast<long>(sm.number_of_edges()) +
                     static_cast<long>(sm.number_of_faces());
  if (euler != 2) {
    why = "The organ's surface has Euler characteristic " + std::to_string(euler) + " (" +
          quantity(static_cast<std::size_t>((2 - euler) / 2), "handle", "handles") +
          "): a geometry image needs a closed piece without handles (2).";
    return std::nullopt;
  }
  if (PMP::volume(sm) < 0) PMP::reverse_face_orientations(sm);

  // Candidates: the seam along each principal axis, each map asked for; the one whose grid lies nearest the surface
  // (CGAL's Hausdorff distance, 20,000 samples) is kept: a seam through a region the map squeezes undersamples it.
  std::optional<GeometryImage> best;
  double bestDistance = std::numeric_limits<double>::infinity();
  std::string lastWhy;
  const std::vector<SurfaceMap> maps = settings.map == SurfaceMap::Best
                                           ? std::vector<SurfaceMap>{SurfaceMap::Authalic, SurfaceMap::Conformal,
                                                                     SurfaceMap::MeanValue, SurfaceMap::Stretch}
                                           : std::vector<SurfaceMap>{settings.map};
  // (the source's own triangles are mapped: remeshing them evenly first was tried, 0.7 grid steps, and made the
  // reconstruction 1-2x farther from the organ: the remeshed surface moved off the file's)
  GeometryImage source;  // (its surface only)
  {
    std::map<SMV, int> at;
    for (auto v : sm.vertices())
      at[v] = static_cast<int>(source.sourcePoints.size()), source.sourcePoints.push_back(eig(sm.point(v)));
    for (auto f : sm.faces()) {
      std::array<int, 3> t{};
      int k = 0;
      for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm))
        if (k < 3) t[static_cast<std::size_t>(k++)] = at[v];
      source.sourceTriangles.push_back(t);
    }
  }
  // Every map along each seam of the tree as it grows, at `n` x `n`; the nearest kept. False when cancelled.
  const double candidates = static_cast<double>(maps.size()) * (settings.seamBranches + 1);
  int tried = 0;
  bool cancelled = false;
  auto search = [&](int n) {
    for (SurfaceMap map : maps) {
      std::vector<SMV> branches;
      for (int round = 0; round <= settings.seamBranches && !cancelled; ++round) {
        // (a grown grid's search goes on past the first one's share: told as 99 %)
        if (settings.progress && !settings.progress(std::min(0.99, tried++ / candidates))) cancelled = true;
        if (cancelled) break;
        auto gi = imageAlong(sm, 2, map, n, branches, lastWhy);
        if (!gi) break;
        const double d =
            surfaceHausdorff(source.sourcePoints, source.sourceTriangles, gi->points, gi->triangles(), 20000);
        // The surface's vertex farthest from the grid's samples: the next branch of the seam goes there.
        std::size_t worst = 0;
        double worstDistance = -1;
        for (std::size_t v = 0; v < source.sourcePoints.size(); ++v) {
          double nearest = std::numeric_limits<double>::infinity();
          for (const auto& q : gi->points) nearest = std::min(nearest, (q - source.sourcePoints[v]).squaredNorm());
          if (nearest > worstDistance) worstDistance = nearest, worst = v;
        }
        if (d >= 0 && d < bestDistance) bestDistance = d, best = std::move(gi), best->map = map;
        branches.push_back(SMV(static_cast<std::uint32_t>(worst)));
      }
    }
  };
  search(settings.size);
  if (cancelled) {
    why = "The geometry image was cancelled.";
    return std::nullopt;
  }
  if (!best) {
    why = lastWhy;
    return std::nullopt;
  }
  // A finer grid while the nearest lies farther from the surface than the tolerance (the whole search again: the map
  // and seam nearest at one size are not always nearest at the next; measured on scikit-surgery's kidney, the 81 x 81
  // choice resampled at 161 x 161 stayed at 2.6 %, the search there reached 1.9 %).
  double extent = 0;
  {
    Eigen::AlignedBox3d box;
    for (const auto& p : source.sourcePoints) box.extend(p);
    extent = box.diagonal().norm();
  }
  const int grow = std::max(1, (settings.size - 1) / 2);
  for (int n = settings.size + grow; n <= settings.maxSize && bestDistance > settings.tolerance * extent; n += grow) {
    search(n);
    if (cancelled) {
      why = "The geometry image was cancelled.";
      return std::nullopt;
    }
  }
  if (settings.progress) settings.progress(1.0);
  best->hausdorff = bestDistance;
  best->extent = extent;
  best->droppedPieces = static_cast<int>(pieces);
  best->sourcePoints = std::move(source.sourcePoints);
  best->sourceTriangles = std::move(source.sourceTriangles);
  best->filledHoles = filled;
  return best;
}

double surfaceHausdorff(const std::vector<Eigen::Vector3d>& pointsA, const std::vector<std::array<int, 3>>& trianglesA,
                        const std::vector<Eigen::Vector3d>& pointsB, const std::vector<std::array<int, 3>>& trianglesB,
                        int samples) {
  SM a, b;
  if (!toSurfaceMesh(pointsA, trianglesA, a, false) || !toSurfaceMesh(pointsB, trianglesB, b, false)) return -1;
  const double areaA = PMP::area(a), areaB = PMP::area(b);
  if (!(areaA > 0) || !(areaB > 0)) return -1;
  // Grid sampling (a spacing giving about `samples` points): the same surfaces give the same distance in every run and
  // on every thread (the geometry image's choice of map rests on it, and a replay of the FFD model rebuilds the same
  // image). CGAL's default random sampling draws from the thread's default generator, which goes on from call to call:
  // the same candidates gave 0.88-1.02 mm on the liver preset, and another map was chosen.
  const double ab = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(
      a, b, CGAL::parameters::use_grid_sampling(true).grid_spacing(std::sqrt(areaA / samples)));
  const double ba = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(
      b, a, CGAL::parameters::use_grid_sampling(true).grid_spacing(std::sqrt(areaB / samples)));
  return std::max(ab, ba);
}

}  // namespace rehearse::simcore
