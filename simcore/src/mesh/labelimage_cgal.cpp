// Label images with CGAL: the meshing of any label image through CGAL's
// labelled-image interpolation (Image_3::labellized_trilinear_interpolation) and our Mesh_3 driver
// (tetrahedraliseImplicit: progress, cancel, element count).
#include <rehearse/simcore/labelimage.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <CGAL/Image_3.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <set>

namespace rehearse::simcore {

namespace {

std::string litres(double cubicMetres) {
  char text[32];
  if (cubicMetres >= 1e-4)
    std::snprintf(text, sizeof text, "%.3f L", cubicMetres * 1e3);
  else
    std::snprintf(text, sizeof text, "%.2f mL", cubicMetres * 1e6);
  return text;
}

double tetVolume(const Mesh& m, const std::array<int, 4>& t) {
  const Eigen::Vector3d& a = m.points[static_cast<std::size_t>(t[0])];
  return (m.points[static_cast<std::size_t>(t[1])] - a)
             .dot((m.points[static_cast<std::size_t>(t[2])] - a).cross(m.points[static_cast<std::size_t>(t[3])] - a)) /
         6.0;
}

}  // namespace

Mesh meshLabelImage(const LabelImage& image, const LabelMeshOptions& options, std::vector<std::string>* notes) {
  const long nx = image.size[0], ny = image.size[1], nz = image.size[2];
  if (nx < 1 || ny < 1 || nz < 1 || image.labels.size() != static_cast<std::size_t>(nx * ny * nz))
    throw MeshError("The label image's size does not match its voxels; it cannot be meshed.");
  if (options.ras && image.frame != "LPS")
    throw MeshError("The image stores no orientation (" + image.format +
                    "), so it cannot be put in RAS; mesh it in its own axes.");
  std::map<int, long> counts = image.labelCounts();
  std::set<int> wanted;
  for (int l : options.only) {
    if (!counts.count(l))
      throw MeshError("The image has no voxel labelled " + std::to_string(l) +
                      "; its labels are listed by `rehearse info`.");
    wanted.insert(l);
  }
  if (wanted.empty())
    for (const auto& [l, c] : counts) wanted.insert(l);
  if (wanted.empty()) throw MeshError("The image has no labelled voxel; there is nothing to mesh.");

  // The labels in CGAL's image, padded by one background voxel on every side (a label touching the image's edge is
  // closed half a voxel beyond its last voxel, as inside), voxel size 1: our label function scales to voxels itself,
  // so anisotropic voxels are meshed in metres.
  const std::size_t px = static_cast<std::size_t>(nx + 2), py = static_cast<std::size_t>(ny + 2),
                    pz = static_cast<std::size_t>(nz + 2);
  _image* raw = ::_createImage(px, py, pz, 1, 1.0, 1.0, 1.0, 4, WK_FIXED, SGN_SIGNED);
  if (!raw) throw MeshError("Not enough memory to mesh the label image.");
  CGAL::Image_3 padded(raw);
  auto* data = static_cast<std::int32_t*>(raw->data);
  std::fill(data, data + px * py * pz, 0);
  for (long k = 0; k < nz; ++k)
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i) {
        const std::int32_t l = image.labels[static_cast<std::size_t>(i + nx * (j + ny * k))];
        data[static_cast<std::size_t>(i + 1) +
             px * (static_cast<std::size_t>(j + 1) + py * static_cast<std::size_t>(k + 1))] = wanted.count(l) ? l : 0;
      }
  const Eigen::Vector3d s = image.spacing;
  // Mesh space: metres along the image's axes, padded voxel (0,0,0) at 0.
  LabelFunction label = [&padded, s](const Eigen::Vector3d& p) {
    return padded.labellized_trilinear_interpolation<std::int32_t, double, int>(p.x() / s.x(), p.y() / s.y(),
                                                                                p.z() / s.z(), 0);
  };
  Eigen::AlignedBox3d bounds(Eigen::Vector3d::Zero(),
                             Eigen::Vector3d(static_cast<double>(px - 1) * s.x(), static_cast<double>(py - 1) * s.y(),
                                             static_cast<double>(pz - 1) * s.z()));
  double voxelVolume = 0;
  for (int l : wanted) voxelVolume += static_cast<double>(counts[l]) * image.voxelVolume();
  Mesh m = tetrahedraliseImplicit(label, bounds, options.tetrahedralise, voxelVolume);

  // To the patient (or image) frame: unpad, scale is already metres, then origin + direction.
  Eigen::Matrix3d frame = image.direction;
  Eigen::Vector3d origin = image.origin;
  if (options.ras) {
    frame.row(0) *= -1;
    frame.row(1) *= -1;
    origin.x() = -origin.x();
    origin.y() = -origin.y();
  }
  for (auto& p : m.points) p = origin + frame * (p - s);
  if (frame.determinant() < 0)
    for (auto& t : m.tets) std::swap(t[1], t[2]);  // a mirrored frame: keep the tets positively oriented
  m.unitToMetre = 1.0;
  std::map<int, double> meshed;
  for (std::size_t t = 0; t < m.tets.size(); ++t) meshed[m.tetLabels[t]] += tetVolume(m, m.tets[t]);
  auto nameOf = [&](int l) {
    auto it = image.names.find(l);
    return it != image.names.end() ? it->second : "label " + std::to_string(l);
  };
  for (int l : wanted)
    if (image.names.count(l)) m.setLabelName(l, image.names.at(l));
  if (notes) {
    notes->push_back(std::string("Coordinates: metres in ") +
                     (image.frame != "LPS" ? "the image's own axes"
                      : options.ras        ? "RAS (x to the patient's right, y anterior, z superior)"
                                           : "LPS (x to the patient's left, y posterior, z superior; ITK and DICOM)") +
                     ", from the image's origin, spacing and direction.");
    for (int l : wanted) {
      const double voxels = static_cast<double>(counts[l]) * image.voxelVolume();
      const double got = meshed.count(l) ? meshed[l] : 0.0;
      char text[200];
      std::snprintf(text, sizeof text, "%s: %s meshed, %s of voxels (%+.1f %%).", nameOf(l).c_str(),
                    litres(got).c_str(), litres(voxels).c_str(), 100.0 * (got - voxels) / voxels);
      notes->push_back(text);
    }
  }
  return m;
}

}  // namespace rehearse::simcore
