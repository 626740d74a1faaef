// The parameterized mesh's deformation and force (paramesh.hpp): nearest-vertex tracking on the grid, Gaussian FFD in
// parameter space, Hertz's normal force and a linear tangential spring with Coulomb slip.
#include <rehearse/simcore/paramesh.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rehearse::simcore {

const char* surfaceMapName(SurfaceMap map) {
  switch (map) {
    case SurfaceMap::Authalic:
      return "authalic";
    case SurfaceMap::Conformal:
      return "conformal";
    case SurfaceMap::MeanValue:
      return "mean value";
    case SurfaceMap::Stretch:
      return "stretch-minimising";
    case SurfaceMap::Best:
      break;
  }
  return "best";
}

double hertzForce(double r, double effectiveModulus, double depth) {
  if (!(depth > 0) || !(r > 0) || !(effectiveModulus > 0)) return 0;
  return 4.0 / 3.0 * std::sqrt(r) * effectiveModulus * std::pow(depth, 1.5);
}

double rigidToolModulus(double youngModulus, double poisson) { return youngModulus / (1 - poisson * poisson); }

ParameterizedMesh::ParameterizedMesh(GeometryImage image, const FfdSettings& settings)
    : image_(std::move(image)),
      settings_(settings),
      x_(image_.points),
      step_(image_.points.size(), 0),
      seen_(image_.points.size(), 0) {
  queue_.reserve(image_.points.size());
  touched_.reserve(image_.points.size());
  const int n = image_.size;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      double sum = 0;
      int count = 0;
      for (const auto& [di, dj] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
        const int a = i + di, b = j + dj;
        if (a < 0 || b < 0 || a >= n || b >= n) continue;
        sum += (image_.points[static_cast<std::size_t>(image_.index(a, b))] -
                image_.points[static_cast<std::size_t>(image_.index(i, j))])
                   .norm();
        ++count;
      }
      step_[static_cast<std::size_t>(image_.index(i, j))] = count ? sum / count : 0;
    }
  // The border's points lie on the seam, each beside border points of the seam's other side (sampled at other places
  // along it): their twins within 1.5 grid steps, so that the walk crosses the seam.
  twins_.assign(image_.points.size(), {});
  std::vector<int> border;
  for (int k = 0; k < n; ++k)
    for (int v : {image_.index(0, k), image_.index(n - 1, k), image_.index(k, 0), image_.index(k, n - 1)})
      border.push_back(v);
  std::sort(border.begin(), border.end());
  border.erase(std::unique(border.begin(), border.end()), border.end());
  for (int a : border)
    for (int b : border)
      if (a != b && (image_.points[static_cast<std::size_t>(a)] - image_.points[static_cast<std::size_t>(b)]).norm() <=
                        1.5 * std::max(step_[static_cast<std::size_t>(a)], 1e-9))
        twins_[static_cast<std::size_t>(a)].push_back(b);
}

double ParameterizedMesh::weight(double s) const {
  const double r = settings_.radius;
  if (!(r > 0) || s > r) return 0;
  const double sigma = r / 3;
  return std::exp(-s * s / (2 * sigma * sigma));
}

int ParameterizedMesh::nearestVertex(const Eigen::Vector3d& p) {
  const int n = image_.size;
  const auto& rest = image_.points;
  auto d2 = [&](int v) { return (rest[static_cast<std::size_t>(v)] - p).squaredNorm(); };
  auto full = [&] {
    int best = 0;
    for (int v = 1; v < n * n; ++v)
      if (d2(v) < d2(best)) best = v;
    return best;
  };
  if (last_ < 0) return last_ = full();
  int v = last_;
  // The walk: to the nearest of the 24 grid neighbours (and their twins across the seam) while it is nearer.
  for (int guard = 0; guard < 4 * n; ++guard) {
    int next = v;
    auto around = [&](int at) {
      const int i = at / n, j = at % n;
      for (int di = -2; di <= 2; ++di)  // two rings: one ring stops in a stretched cell's local minimum
        for (int dj = -2; dj <= 2; ++dj) {
          const int a = i + di, b = j + dj;
          if (a < 0 || b < 0 || a >= n || b >= n) continue;
          if (d2(image_.index(a, b)) < d2(next)) next = image_.index(a, b);
        }
    };
    around(v);
    for (int t : twins_[static_cast<std::size_t>(v)]) around(t);
    if (next == v) break;
    v = next;
  }
  // A walk can stop in a fold's local minimum: farther than two grid steps (a tool above the surface, or a stop), the
  // full search (6,561 distances at 81 x 81: microseconds).
  if (std::sqrt(d2(v)) > 2 * std::max(step_[static_cast<std::size_t>(v)], 1e-9)) v = full();
  return last_ = v;
}

void ParameterizedMesh::deform(int vertex, const Eigen::Vector3d& displacement) {
  for (int v : touched_) x_[static_cast<std::size_t>(v)] = image_.points[static_cast<std::size_t>(v)];
  touched_.clear();
  // The neighbourhood: the grid vertices joined to the tool's through grid neighbours (and across the seam) whose rest
  // distance to it is within the radius; each moves by the Gaussian weight of that distance. (A weight on the grid's
  // own distance would shrink the reach where the map squeezes the surface: there one grid step spans centimetres.)
  const int n = image_.size;
  const Eigen::Vector3d& centre = image_.points[static_cast<std::size_t>(vertex)];
  if (++stamp_ == 0) {  // (wrapped after 4 billion updates: the marks start again)
    std::fill(seen_.begin(), seen_.end(), 0u);
    stamp_ = 1;
  }
  queue_.clear();
  queue_.push_back(vertex);
  seen_[static_cast<std::size_t>(vertex)] = stamp_;
  for (std::size_t head = 0; head < queue_.size(); ++head) {
    const int v = queue_[head];
    const double w = weight((image_.points[static_cast<std::size_t>(v)] - centre).norm());
    x_[static_cast<std::size_t>(v)] = image_.points[static_cast<std::size_t>(v)] + w * displacement;
    touched_.push_back(v);
    auto visit = [&](int u) {
      if (seen_[static_cast<std::size_t>(u)] == stamp_) return;
      seen_[static_cast<std::size_t>(u)] = stamp_;
      if ((image_.points[static_cast<std::size_t>(u)] - centre).norm() <= settings_.radius) queue_.push_back(u);
    };
    const int i = v / n, j = v % n;
    if (i > 0) visit(v - n);
    if (i + 1 < n) visit(v + n);
    if (j > 0) visit(v - 1);
    if (j + 1 < n) visit(v + 1);
    for (int t : twins_[static_cast<std::size_t>(v)]) visit(t);
  }
}

ParameterizedMesh::Contact ParameterizedMesh::poke(const Eigen::Vector3d& tip) {
  Contact c;
  const int v = nearestVertex(tip);
  const Eigen::Vector3d& p = image_.points[static_cast<std::size_t>(v)];
  const Eigen::Vector3d& nrm = image_.normals[static_cast<std::size_t>(v)];
  c.vertex = v;
  c.normal = nrm;
  c.depth = (p - tip).dot(nrm);
  if (!(c.depth > 0)) {
    release();
    c.depth = 0;
    return c;
  }
  c.touching = true;
  Eigen::Vector3d d = tip - p;
  if (d.norm() > settings_.maxDisplacement) {
    d *= settings_.maxDisplacement / d.norm();
    c.clamped = true;
  }
  deform(v, d);
  const double depth = std::min(c.depth, settings_.maxDisplacement);
  c.normalForce = hertzForce(settings_.toolRadius, rigidToolModulus(settings_.youngModulus, settings_.poisson), depth);
  // Tangential: a spring from where the contact began (on the rest surface), slipping past mu F_n.
  const Eigen::Vector3d onSurface = tip + c.depth * nrm;
  if (!anchored_) anchor_ = onSurface, anchored_ = true;
  Eigen::Vector3d dt = onSurface - anchor_;
  dt -= dt.dot(nrm) * nrm;
  Eigen::Vector3d ft = -settings_.tangentialStiffness * dt;
  const double limit = settings_.friction * c.normalForce;
  if (ft.norm() > limit) {  // slides: the anchor follows so that the spring holds at the cone
    const Eigen::Vector3d dir = dt.normalized();
    ft = -limit * dir;
    anchor_ = onSurface - (settings_.tangentialStiffness > 0 ? limit / settings_.tangentialStiffness : 0.0) * dir;
  }
  c.tangentialForce = ft.norm();
  c.force = c.normalForce * nrm + ft;
  return c;
}

ParameterizedMesh::Contact ParameterizedMesh::hold(int vertex, const Eigen::Vector3d& displacement) {
  Contact c;
  if (vertex < 0 || vertex >= image_.size * image_.size) return c;
  c.touching = true;
  c.vertex = vertex;
  c.normal = image_.normals[static_cast<std::size_t>(vertex)];
  Eigen::Vector3d d = displacement;
  if (d.norm() > settings_.maxDisplacement) {
    d *= settings_.maxDisplacement / d.norm();
    c.clamped = true;
  }
  deform(vertex, d);
  c.depth = d.norm();
  c.normalForce =
      hertzForce(settings_.toolRadius, rigidToolModulus(settings_.youngModulus, settings_.poisson), c.depth);
  c.force = c.depth > 0 ? Eigen::Vector3d(-c.normalForce * d / c.depth) : Eigen::Vector3d::Zero();
  return c;
}

void ParameterizedMesh::release() {
  for (int v : touched_) x_[static_cast<std::size_t>(v)] = image_.points[static_cast<std::size_t>(v)];
  touched_.clear();
  anchored_ = false;
}

}  // namespace rehearse::simcore
