// INR label images read by CGAL's ImageIO (CGAL's own format; its liver example). Apart from the meshing
// (labelimage_cgal.cpp) so the readers can be fuzzed without building Mesh_3.
#include <rehearse/simcore/labelimage.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <CGAL/ImageIO.h>

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <cstdint>
#include <filesystem>
#include <memory>

namespace rehearse::simcore {

LabelImage readInrLabelImage(const std::string& path, std::size_t maxVoxels);

namespace {

struct ImageDeleter {
  void operator()(_image* im) const {
    if (im) ::_freeImage(im);
  }
};

template <typename Word>
void copyWords(const _image* im, std::vector<std::int32_t>& out, std::size_t& fractional) {
  const Word* w = static_cast<const Word*>(im->data);
  for (std::size_t i = 0; i < out.size(); ++i) {
    const double v = static_cast<double>(w[i]);
    if (!(v == std::floor(v)) || v < -2147483648.0 || v > 2147483647.0) {
      ++fractional;
      continue;
    }
    out[i] = static_cast<std::int32_t>(v);
  }
}

}  // namespace

LabelImage readInrLabelImage(const std::string& path, std::size_t maxVoxels) {
  const std::string name = std::filesystem::path(path).filename().string();
  // CGAL's ImageIO chooses its reader by the content, whatever the name: a .inr holding a PGM went to its PNM reader,
  // which loops for ever at the end of a short file (found by fuzzing). Only an INR header goes on.
  {
    char magic[12] = {};
    gzFile z = gzopen(path.c_str(), "rb");  // reads an uncompressed file as it is
    const int got = z ? gzread(z, magic, sizeof magic) : -1;
    if (z) gzclose(z);
    if (got != static_cast<int>(sizeof magic) || std::memcmp(magic, "#INRIMAGE-4#", sizeof magic) != 0)
      throw MeshError(name + " is not an INR image: it does not begin with \"#INRIMAGE-4#\".");
  }
  int error = 0;
  std::unique_ptr<_image, ImageDeleter> im(::_readImageHeaderAndGetError(path.c_str(), &error));
  if (!im || error != 0) throw MeshError("Cannot read " + name + ": it is damaged or not an INR image.");
  const double count = static_cast<double>(im->xdim) * static_cast<double>(im->ydim) * static_cast<double>(im->zdim);
  if (im->vdim != 1)
    throw MeshError(name + " has " + std::to_string(im->vdim) +
                    " values per voxel (a colour or vector image); a segmentation holds one label per voxel.");
  if (im->zdim < 2) throw MeshError(name + " is a 2D image; a segmentation must be a 3D label image.");
  if (!(count >= 1)) throw MeshError(name + " has no voxels.");
  if (count > static_cast<double>(maxVoxels))
    throw MeshError(name + " has " + std::to_string(static_cast<long long>(count / 1e6)) +
                    " million voxels; more than " + std::to_string(maxVoxels / 1000000) +
                    " million cannot be meshed here (crop or resample it first).");
  if (!(im->vx > 0 && im->vy > 0 && im->vz > 0) || !std::isfinite(im->vx * im->vy * im->vz))
    throw MeshError(name + " has a voxel size of zero or less; its header is damaged.");
  if (::_readImageData(im.get()) < 0 || !im->data)
    throw MeshError("Cannot read " + name + "'s voxels: the file ends early or is damaged.");
  LabelImage image;
  image.format = "INR";
  image.frame = "image";
  image.size = {static_cast<long>(im->xdim), static_cast<long>(im->ydim), static_cast<long>(im->zdim)};
  // INR stores sizes in the file's unit, by convention millimetres (CGAL's examples, its liver).
  image.spacing = Eigen::Vector3d(im->vx, im->vy, im->vz) * 1e-3;
  image.origin = Eigen::Vector3d(im->tx, im->ty, im->tz) * 1e-3;
  image.labels.assign(static_cast<std::size_t>(count), 0);
  std::size_t fractional = 0;
  const bool isSigned = im->sign == SGN_SIGNED;
  if (im->wordKind == WK_FLOAT) {
    if (im->wdim == 4)
      copyWords<float>(im.get(), image.labels, fractional);
    else if (im->wdim == 8)
      copyWords<double>(im.get(), image.labels, fractional);
    else
      throw MeshError(name + " stores voxels in a word size this program does not read.");
  } else if (im->wordKind == WK_FIXED) {
    switch (im->wdim) {
      case 1:
        isSigned ? copyWords<std::int8_t>(im.get(), image.labels, fractional)
                 : copyWords<std::uint8_t>(im.get(), image.labels, fractional);
        break;
      case 2:
        isSigned ? copyWords<std::int16_t>(im.get(), image.labels, fractional)
                 : copyWords<std::uint16_t>(im.get(), image.labels, fractional);
        break;
      case 4:
        isSigned ? copyWords<std::int32_t>(im.get(), image.labels, fractional)
                 : copyWords<std::uint32_t>(im.get(), image.labels, fractional);
        break;
      default:
        throw MeshError(name + " stores voxels in a word size this program does not read.");
    }
  } else {
    throw MeshError(name + " stores voxels of a kind this program does not read.");
  }
  if (fractional > 0)
    throw MeshError(name + " holds values that are not labels (" + std::to_string(fractional) +
                    " voxels are not whole numbers: a CT or MRI?); segment it into a label image first.");
  image.notes.push_back(name +
                        " (INR) stores no orientation: the mesh is in the image's own axes (x along its "
                        "columns, y its rows, z its slices), not a patient frame.");
  return image;
}

}  // namespace rehearse::simcore
