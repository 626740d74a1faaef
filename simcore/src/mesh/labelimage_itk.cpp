// Label images through ITK's image IO (NRRD, NIfTI, MetaImage): the only file that includes ITK, and it includes
// nothing of Eigen (ITK 5.2's bundled Eigen shares the system one's include guards).
#include "labelimage_raw.hpp"

#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIOFactory.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>

namespace rehearse::simcore::detail {
namespace {

std::string fileName(const std::string& path) { return std::filesystem::path(path).filename().string(); }

void registerFormats() {
  static std::once_flag once;
  std::call_once(once, [] {
    itk::NrrdImageIOFactory::RegisterOneFactory();
    itk::NiftiImageIOFactory::RegisterOneFactory();
    itk::MetaImageIOFactory::RegisterOneFactory();
  });
}

// ITK's exception text is several lines with a source location; the user gets its last line.
std::string itkReason(const itk::ExceptionObject& e) {
  std::string d = e.GetDescription();
  while (!d.empty() && std::isspace(static_cast<unsigned char>(d.back()))) d.pop_back();
  if (auto nl = d.rfind('\n'); nl != std::string::npos) d = d.substr(nl + 1);
  while (!d.empty() && std::isspace(static_cast<unsigned char>(d.front()))) d.erase(d.begin());
  if (d.size() > 160) d = d.substr(0, 157) + "...";
  if (d.empty()) d = "it is damaged";
  if (d.back() != '.') d += '.';
  return d;
}

// 3D Slicer's segmentation header: Segment<i>_Name and Segment<i>_LabelValue (label i + 1 when absent).
std::map<int, std::string> slicerSegmentNames(const itk::MetaDataDictionary& dict) {
  std::map<int, std::string> names;
  for (int i = 0; i < 1000; ++i) {
    std::string name, value;
    if (!itk::ExposeMetaData<std::string>(dict, "Segment" + std::to_string(i) + "_Name", name)) break;
    int label = i + 1;
    if (itk::ExposeMetaData<std::string>(dict, "Segment" + std::to_string(i) + "_LabelValue", value)) {
      try {
        label = std::stoi(value);
      } catch (...) {
        continue;
      }
    }
    if (label != 0 && !name.empty() && name.size() <= 200) names[label] = name;
  }
  return names;
}

template <typename Pixel>
typename itk::Image<Pixel, 3>::Pointer readAs(itk::ImageIOBase* io, const std::string& path) {
  auto reader = itk::ImageFileReader<itk::Image<Pixel, 3>>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path);
  reader->Update();
  return reader->GetOutput();
}

}  // namespace

RawLabelImage itkReadLabelImage(const std::string& path, std::size_t maxVoxels) {
  registerFormats();
  const std::string name = fileName(path);
  itk::ImageIOBase::Pointer io =
      itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::ImageIOFactory::IOFileModeEnum::ReadMode);
  if (!io) throw LabelImageError("Cannot read " + name + ": it is damaged or not a NRRD, NIfTI or MetaImage file.");
  RawLabelImage image;
  try {
    io->SetFileName(path);
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    throw LabelImageError("Cannot read " + name + ": " + itkReason(e));
  }
  const unsigned dims = io->GetNumberOfDimensions();
  if (dims < 3)
    throw LabelImageError(name + " is a " + std::to_string(dims) + "D image; a segmentation is a 3D label image.");
  for (unsigned d = 3; d < dims; ++d)
    if (io->GetDimensions(d) > 1)
      throw LabelImageError(
          name + " has " + std::to_string(io->GetDimensions(d)) +
          " layers (a 4D image, as 3D Slicer saves overlapping segments); export it as one label map.");
  if (io->GetNumberOfComponents() != 1)
    throw LabelImageError(name + " has " + std::to_string(io->GetNumberOfComponents()) +
                          " values per voxel (a colour or vector image); a segmentation holds one label per voxel.");
  double count = 1;
  for (int d = 0; d < 3; ++d) {
    image.size[d] = static_cast<long>(io->GetDimensions(d));
    count *= static_cast<double>(io->GetDimensions(d));
  }
  if (!(count >= 1)) throw LabelImageError(name + " has no voxels.");
  if (count > static_cast<double>(maxVoxels))
    throw LabelImageError(name + " has " + std::to_string(static_cast<long long>(count / 1e6)) +
                          " million voxels; more than " + std::to_string(maxVoxels / 1000000) +
                          " million cannot be meshed here (crop or resample it first).");
  for (int d = 0; d < 3; ++d) {
    image.spacingMm[d] = io->GetSpacing(d);  // ITK reports millimetres
    image.originMm[d] = io->GetOrigin(d);
    const std::vector<double> axis = io->GetDirection(d);
    for (int r = 0; r < 3; ++r) image.direction[r * 3 + d] = r < static_cast<int>(axis.size()) ? axis[r] : 0.0;
  }
  const auto component = io->GetComponentType();
  using C = itk::IOComponentEnum;
  const bool smallInteger = component == C::UCHAR || component == C::CHAR || component == C::USHORT ||
                            component == C::SHORT || component == C::INT;
  try {
    image.labels.resize(static_cast<std::size_t>(count));
    if (smallInteger) {
      auto img = readAs<std::int32_t>(io, path);
      std::copy_n(img->GetBufferPointer(), image.labels.size(), image.labels.begin());
    } else {
      auto img = readAs<double>(io, path);
      const double* v = img->GetBufferPointer();
      std::size_t fractional = 0;
      for (std::size_t i = 0; i < image.labels.size(); ++i) {
        if (!(v[i] == std::floor(v[i])) || v[i] < std::numeric_limits<std::int32_t>::min() ||
            v[i] > std::numeric_limits<std::int32_t>::max()) {
          ++fractional;
          continue;
        }
        image.labels[i] = static_cast<std::int32_t>(v[i]);
      }
      if (fractional > 0)
        throw LabelImageError(name + " holds values that are not labels (" + std::to_string(fractional) +
                              " voxels are not whole numbers: a CT or MRI?); segment it into a label image first.");
      if (component == C::FLOAT || component == C::DOUBLE)
        image.notes.push_back(
            name + " stores its labels as floating-point numbers; all are whole, so they were taken as labels.");
    }
  } catch (const itk::ExceptionObject& e) {
    throw LabelImageError("Cannot read " + name + "'s voxels: " + itkReason(e));
  } catch (const std::bad_alloc&) {
    throw LabelImageError("Cannot read " + name + ": not enough memory for its voxels.");
  }
  const std::string lower = [&] {
    std::string l = name;
    for (auto& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return l;
  }();
  image.format = lower.find(".nrrd") != std::string::npos || lower.find(".nhdr") != std::string::npos ? "NRRD"
                 : lower.find(".nii") != std::string::npos                                            ? "NIfTI"
                                                                                                      : "MetaImage";
  if (image.format == "NRRD") {
    image.names = slicerSegmentNames(io->GetMetaDataDictionary());
    if (!image.names.empty())
      image.notes.push_back("Labels named from the segment names in " + name + "'s header (3D Slicer).");
  }
  return image;
}

void itkWriteLabelImage(const RawLabelImage& image, const std::string& path) {
  registerFormats();
  using Image = itk::Image<std::int32_t, 3>;
  if (image.labels.size() != static_cast<std::size_t>(image.size[0] * image.size[1] * image.size[2]))
    throw LabelImageError("The label image's size does not match its voxels; nothing was written.");
  auto img = Image::New();
  Image::SizeType size;
  Image::SpacingType spacing;
  Image::PointType origin;
  Image::DirectionType direction;
  for (int d = 0; d < 3; ++d) {
    size[d] = static_cast<itk::SizeValueType>(image.size[d]);
    spacing[d] = image.spacingMm[d];
    origin[d] = image.originMm[d];
    for (int r = 0; r < 3; ++r) direction(r, d) = image.direction[r * 3 + d];
  }
  Image::RegionType region;
  region.SetSize(size);
  img->SetRegions(region);
  img->SetSpacing(spacing);
  img->SetOrigin(origin);
  img->SetDirection(direction);
  img->Allocate();
  std::copy(image.labels.begin(), image.labels.end(), img->GetBufferPointer());
  auto writer = itk::ImageFileWriter<Image>::New();
  writer->SetFileName(path);
  writer->SetInput(img);
  writer->SetUseCompression(true);
  try {
    writer->Update();
  } catch (const itk::ExceptionObject& e) {
    throw LabelImageError("Cannot write " + fileName(path) + ": " + itkReason(e));
  }
}

}  // namespace rehearse::simcore::detail
