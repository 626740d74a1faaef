// libFuzzer entry point for the label-image readers as a user reaches them (simcore::readLabelImage): our header
// checks, then ITK's NRRD, NIfTI and MetaImage readers and CGAL's INR reader (the libraries are not instrumented:
// their crashes, hangs and memory past the limit are still findings). The first byte chooses the format; the rest is
// the file. A refusal (MeshError) is the expected outcome of most inputs; a crash, a hang or any other exception is a
// finding. The voxel limit is small here so that a header's size, not the fuzzer's memory, decides.
#include <rehearse/simcore/labelimage.hpp>
#include <rehearse/simcore/mesh.hpp>

#include "fuzz_file.hpp"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  readAsFile(data, size, {".nrrd", ".nhdr", ".nii", ".nii.gz", ".mha", ".mhd", ".inr", ".inr.gz"}, "image",
             [](const std::string& path) {
               try {
                 rehearse::simcore::readLabelImage(path, {}, 4'000'000);
               } catch (const rehearse::simcore::MeshError&) {
               }
             });
  return 0;
}
