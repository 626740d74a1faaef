#pragma once
// Segmentations as input (issue 39): a label image (NRRD, NIfTI, MetaImage, INR) from 3D Slicer, ITK-SNAP or a
// radiology workstation, meshed into a labelled tetrahedral mesh with CGAL Mesh_3, each label a part.
//
// Readers: ITK's image IO (Debian's libinsighttoolkit5) for NRRD, NIfTI and MetaImage, which keeps each file's
// spacing, origin and direction in the patient frame ITK and DICOM use (LPS: x to the patient's left, y posterior,
// z superior); CGAL's own ImageIO for INR (CGAL's format, which stores no orientation). Only the ITK headers' one
// source file (labelimage_itk.cpp) and the CGAL one (labelimage_cgal.cpp) see those libraries.
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// The largest label image read: 400 million voxels (1.6 GB of labels; a 512 x 512 x 1500 CT is 393 million).
inline constexpr std::size_t kMaxLabelVoxels = 400'000'000;

struct LabelImage {
  std::array<long, 3> size{0, 0, 0};                        ///< voxels along the image's i, j, k axes
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();        ///< metres between voxel centres along i, j, k
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();         ///< metres: the centre of voxel (0, 0, 0), in `frame`
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  ///< columns: the i, j, k axes in `frame` (orthonormal)
  std::vector<std::int32_t> labels;                         ///< i fastest, then j, then k; 0 is background
  std::map<int, std::string> names;                         ///< label -> name, when the file or a colour table names it
  std::string format;                                       ///< "NRRD", "NIfTI", "MetaImage" or "INR"
  /// "LPS" (the patient frame, as the file gives it through ITK) or "image" (INR: no orientation stored; the
  /// image's own axes).
  std::string frame = "LPS";
  std::vector<std::string> notes;  ///< what the reader decided (a colour table used, a float image taken as labels)

  std::size_t voxelCount() const { return labels.size(); }
  double voxelVolume() const { return spacing.prod(); }
  /// Voxels per label (background 0 left out), in label order.
  std::map<int, long> labelCounts() const;
  /// The physical point (metres, `frame`) of continuous voxel coordinates (voxel centres at whole numbers).
  Eigen::Vector3d toPhysical(const Eigen::Vector3d& ijk) const {
    return origin + direction * spacing.cwiseProduct(ijk);
  }
};

/// Reads a label image: .nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd (ITK) or .inr/.inr.gz (CGAL). Voxels must hold whole
/// numbers (a CT or MRI is refused: it needs segmenting first). Labels are named from, in order: a colour table
/// given as `colourTable`; one beside the image (STEM.ctbl, STEM_ColorTable.ctbl as 3D Slicer writes, or STEM.txt /
/// STEM.label as ITK-SNAP exports its label descriptions); 3D Slicer's segment names in a .seg.nrrd header.
/// Throws MeshError with one sentence for a missing, damaged, 2D, 4D, multi-component, non-integer, empty or
/// too large (> maxVoxels) image.
LabelImage readLabelImage(const std::string& path, const std::string& colourTable = {},
                          std::size_t maxVoxels = kMaxLabelVoxels);

/// Writes a label image as NRRD (.nrrd), NIfTI (.nii, .nii.gz) or MetaImage (.mha) with ITK, keeping its spacing,
/// origin and direction (LPS). Throws MeshError with one sentence when it cannot.
void writeLabelImage(const LabelImage& image, const std::string& path);

/// Parses a colour table's text: 3D Slicer's (`VALUE NAME R G B A` per line) or ITK-SNAP's label description
/// (`IDX R G B A VIS MSH "NAME"`); '#' starts a comment. Lines that are neither are skipped; label 0 is skipped.
std::map<int, std::string> parseColourTable(const std::string& text);

struct LabelMeshOptions {
  TetrahedraliseOptions tetrahedralise;  ///< target count or size, seed, progress and cancel
  /// Put the mesh in RAS (x to the patient's right, y anterior: 3D Slicer's world frame) instead of LPS; refused for
  /// an image with no orientation (INR).
  bool ras = false;
  /// Mesh only these labels (empty: every label in the image).
  std::vector<int> only;
};

/// Meshes a label image with CGAL Mesh_3 (its labelled-image interpolation: each point takes the label that
/// dominates the trilinear interpolation of the eight voxels around it, so boundaries are smooth rather than voxel
/// steps). Each label becomes a tet label of that number, named when the image names it. Coordinates:
/// metres in the image's frame (LPS, or RAS on request). The image is padded by one background voxel, so a label
/// that touches the image's edge is closed there. Notes say the frame and the volume of each label against its
/// voxels. Throws MeshError (one sentence) or Cancelled.
Mesh meshLabelImage(const LabelImage& image, const LabelMeshOptions& options,
                    std::vector<std::string>* notes = nullptr);

/// The labels meshLabelImage was asked for (`options.only`, or every label in the image) that have no element in
/// `mesh`: a part thinner than the elements, left out of an otherwise written mesh. Callers say so (the command line
/// exits 4, step 1's status names them): the mesh is not the segmentation it was asked to be.
std::vector<int> unmeshedLabels(const LabelImage& image, const LabelMeshOptions& options, const Mesh& mesh);

/// "label 7" or "label 7 (tumour)" when the image names it.
std::string describeLabel(const LabelImage& image, int label);

/// Whether a path names a label image format readLabelImage reads (by its extension).
bool isLabelImagePath(const std::string& path);

}  // namespace rehearse::simcore
