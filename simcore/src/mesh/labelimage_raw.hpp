#pragma once
// The label image as ITK's side sees it: standard C++ only. ITK 5.2 bundles its own (older) Eigen under the same
// include guards as the system's, so the file that includes ITK must include nothing of Eigen; labelimage.cpp turns
// this into a LabelImage.
#include <array>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace rehearse::simcore::detail {

struct LabelImageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct RawLabelImage {
  std::array<long, 3> size{0, 0, 0};
  std::array<double, 3> spacingMm{1, 1, 1};
  std::array<double, 3> originMm{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major; column d is axis d
  std::vector<std::int32_t> labels;
  std::map<int, std::string> names;
  std::string format;
  std::vector<std::string> notes;
};

/// NRRD, NIfTI or MetaImage through ITK; throws LabelImageError with one sentence.
RawLabelImage itkReadLabelImage(const std::string& path, std::size_t maxVoxels);
/// Writes with ITK (format from the extension, compressed); throws LabelImageError with one sentence.
void itkWriteLabelImage(const RawLabelImage& image, const std::string& path);

}  // namespace rehearse::simcore::detail
