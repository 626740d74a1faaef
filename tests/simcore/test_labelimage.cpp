// Segmentations (issue 39): CGAL's own liver segmentation (../shared/data/cgal/liver.inr.gz) meshed into a labelled
// tetrahedral mesh whose volume is checked against the image's voxel count x voxel volume; the same labels written as
// NIfTI and NRRD (by ITK) read back bit for bit and mesh to the same mesh, placed where the image's origin, spacing
// and direction put the voxels (LPS, and RAS on request); colour tables and 3D Slicer's segment names; bad, 2D, 4D,
// non-integer, empty and huge images refused with one sentence before anything large is allocated; cancel.
#include "cli_run.hpp"
#include "test_support.hpp"

#include <rehearse/simcore/labelimage.hpp>
#include <rehearse/simcore/quality.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <numbers>

#include <QElapsedTimer>
#include <zlib.h>

using namespace rehearse::simcore;

namespace {

const char* kLiver = "cgal/liver.inr.gz";

std::map<int, double> labelVolumes(const Mesh& m) {
  std::map<int, double> v;
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    const auto& t = m.tets[i];
    v[m.tetLabels[i]] += tetVolume(m.points[t[0]], m.points[t[1]], m.points[t[2]], m.points[t[3]]);
  }
  return v;
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const MeshError& e) {
    return e.what();
  }
  return {};
}

// One sentence: no line break, ends with a full stop, not ITK's or CGAL's multi-line text.
void checkOneSentence(const std::string& e, const char* must) {
  QVERIFY2(!e.empty(), "no error was raised");
  QVERIFY2(e.find('\n') == std::string::npos, e.c_str());
  QVERIFY2(e.size() < 260, e.c_str());
  QVERIFY2(e.back() == '.', e.c_str());
  QVERIFY2(e.find(must) != std::string::npos, e.c_str());
}

// A small label image (9 x 7 x 5, 0.8 x 0.8 x 2.5 mm) with two labels.
LabelImage smallImage() {
  LabelImage image;
  image.size = {9, 7, 5};
  image.spacing = Eigen::Vector3d(0.8, 0.8, 2.5) * 1e-3;
  image.labels.assign(9 * 7 * 5, 0);
  for (std::size_t i = 0; i < image.labels.size(); ++i) image.labels[i] = static_cast<std::int32_t>(i % 7 == 0 ? 3 : i % 5 == 0);
  return image;
}

// Refused with one sentence naming the file and containing `must`; with `cli`, `rehearse info` on it exits 1-123 (no
// signal) within 60 s and 8 GiB, printing one line.
void expectImageRefused(const std::string& file, const char* must, bool cli = false) {
  const std::string e = errorOf([&] { readLabelImage(tempPath(file)); });
  checkOneSentence(e, must);
  QVERIFY2(e.find(file) != std::string::npos, e.c_str());
  if (!cli) return;
  const auto r = testing::run({"info", QString::fromStdString(tempPath(file))}, 60000, nullptr, /*boundMemory=*/true);
  QVERIFY2(r.code >= 1 && r.code <= 123 && r.err.trimmed().count('\n') == 0 && r.err.contains(must),
           qPrintable(QString("exit %1: %2").arg(r.code).arg(r.err)));
}

std::string gzipped(const std::string& bytes, const std::string& path) {
  gzFile z = gzopen(path.c_str(), "wb");
  gzwrite(z, bytes.data(), static_cast<unsigned>(bytes.size()));
  gzclose(z);
  return readFile(path);
}

// The liver's labels with a spherical "tumour" (label 2) carved inside it, on float-exact spacing and origin (NIfTI
// stores them as 32-bit floats), with a direction that mirrors and rotates the axes (det -1: tets must be flipped).
LabelImage liverWithTumour(double* tumourRadiusMm, Eigen::Vector3d* tumourCentreIjk) {
  LabelImage image = readLabelImage(sharedData(kLiver));
  image.spacing = Eigen::Vector3d(0.75, 0.75, 1.5) * 1e-3;  // anisotropic, as CT slices are
  image.origin = Eigen::Vector3d(-120.5, 80.25, -310.0) * 1e-3;
  image.direction << 0, 1, 0,  //
      1, 0, 0,                 //
      0, 0, 1;                 // i -> y, j -> x, k -> z: a mirrored frame (det -1)
  // A point inside the liver: the centroid of its voxels (the tumour's voxel count is checked against a sphere's
  // volume, so a centroid outside the liver would fail the test).
  // The liver is the label with the most voxels (255 in CGAL's file; 127 and 85 are its vessels).
  int liver = 0;
  long most = 0;
  for (const auto& [label, count] : image.labelCounts())
    if (count > most) most = count, liver = label;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  long n = 0;
  for (long k = 0; k < image.size[2]; ++k)
    for (long j = 0; j < image.size[1]; ++j)
      for (long i = 0; i < image.size[0]; ++i)
        if (image.labels[static_cast<std::size_t>(i + image.size[0] * (j + image.size[1] * k))] == liver) {
          c += Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
          ++n;
        }
  c /= static_cast<double>(n);
  const double r = 15.0;  // mm
  for (long k = 0; k < image.size[2]; ++k)
    for (long j = 0; j < image.size[1]; ++j)
      for (long i = 0; i < image.size[0]; ++i) {
        const Eigen::Vector3d d =
            (Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)) - c)
                .cwiseProduct(image.spacing * 1e3);
        auto& l = image.labels[static_cast<std::size_t>(i + image.size[0] * (j + image.size[1] * k))];
        if (d.norm() < r && l == liver) l = 2;
      }
  *tumourRadiusMm = r;
  *tumourCentreIjk = c;
  return image;
}

}  // namespace

class TestLabelImage : public QObject {
  Q_OBJECT
 private slots:
  // CGAL's liver segmentation: read by CGAL's ImageIO, meshed by Mesh_3; each label's meshed volume against its voxel
  // count x voxel volume (the acceptance: within 2 %), a positive, conforming, reasonable mesh.
  void liverInrImportsWithinTwoPercent() {
    REQUIRE_SHARED(kLiver);
    LabelImage image = readLabelImage(sharedData(kLiver));
    QCOMPARE(image.format, std::string("INR"));
    QCOMPARE(image.frame, std::string("image"));
    const auto counts = image.labelCounts();
    QVERIFY(!counts.empty());
    qInfo("liver.inr.gz: %ld x %ld x %ld voxels of %.4f x %.4f x %.4f mm, %zu labels, label 1: %ld voxels",
          image.size[0], image.size[1], image.size[2], image.spacing.x() * 1e3, image.spacing.y() * 1e3,
          image.spacing.z() * 1e3, counts.size(), counts.begin()->second);
    LabelMeshOptions o;
    o.tetrahedralise.targetTets = 20000;
    std::vector<std::string> notes;
    const Mesh m = meshLabelImage(image, o, &notes);
    for (const auto& n : notes) qInfo("note: %s", n.c_str());
    const auto q = computeQuality(m);
    qInfo("%zu tets, %zu nodes, min dihedral %.1f deg", m.tets.size(), m.points.size(), q.minDihedralDeg);
    QVERIFY(m.tets.size() > 10000 && m.tets.size() < 40000);
    QCOMPARE(q.inverted, std::size_t(0));
    QVERIFY(q.minDihedralDeg > 2.0);
    // The whole segmentation within 2 %, and each label of 50 mL or more (the liver 1.6 L, its larger vessel tree
    // 160 mL); a thin 9 mL vessel label within 5 % at this element size; labels of a few voxels (label 1: 2 voxels,
    // 84: 4) may get no element, which unmeshedLabels says.
    const auto volumes = labelVolumes(m);
    const std::vector<int> unmeshed = unmeshedLabels(image, o, m);
    double meshedTotal = 0, voxelTotal = 0;
    for (const auto& [label, voxels] : counts) {
      const double expected = static_cast<double>(voxels) * image.voxelVolume();
      const double got = volumes.count(label) ? volumes.at(label) : 0.0;
      meshedTotal += got;
      voxelTotal += expected;
      qInfo("label %d: %ld voxels, meshed %.3f mL, voxels %.3f mL (%+.2f %%)", label, voxels, got * 1e6, expected * 1e6,
            100 * (got - expected) / expected);
      if (expected >= 50e-6)
        QVERIFY2(std::abs(got - expected) < 0.02 * expected, "a label's volume is off by 2 % or more");
      else if (expected >= 5e-6)
        QVERIFY2(std::abs(got - expected) < 0.05 * expected, "a small label's volume is off by 5 % or more");
      // A label with no element is one unmeshedLabels names (the command line exits 4 on it, step 1 says it), and
      // only such a label.
      QCOMPARE(std::count(unmeshed.begin(), unmeshed.end(), label), got == 0 ? 1 : 0);
    }
    qInfo("all labels: meshed %.2f mL, voxels %.2f mL (%+.2f %%)", meshedTotal * 1e6, voxelTotal * 1e6,
          100 * (meshedTotal - voxelTotal) / voxelTotal);
    QVERIFY(std::abs(meshedTotal - voxelTotal) < 0.02 * voxelTotal);
    // The mesh lies within the labelled voxels' box (half a voxel beyond their centres, plus a tenth for the surface).
    Eigen::AlignedBox3d voxels;
    for (long k = 0; k < image.size[2]; ++k)
      for (long j = 0; j < image.size[1]; ++j)
        for (long i = 0; i < image.size[0]; ++i)
          if (image.labels[static_cast<std::size_t>(i + image.size[0] * (j + image.size[1] * k))] != 0)
            voxels.extend(image.toPhysical(
                Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k))));
    const Eigen::Vector3d slack = 0.6 * image.spacing;
    QVERIFY((m.bounds().min() - (voxels.min() - slack)).minCoeff() >= 0);
    QVERIFY(((voxels.max() + slack) - m.bounds().max()).minCoeff() >= 0);
    QVERIFY((m.bounds().sizes() - voxels.sizes()).cwiseAbs().maxCoeff() < 2.0 * image.spacing.maxCoeff());
  }

  // The same labels as NIfTI and as NRRD (written by ITK here): both read back bit for bit with their spacing,
  // origin and direction, mesh to the same mesh, and put the tumour where the direction says.
  void niftiAndNrrdGiveTheSameMesh() {
    REQUIRE_SHARED(kLiver);
    double r = 0;
    Eigen::Vector3d centre;
    LabelImage image = liverWithTumour(&r, &centre);
    QVERIFY(image.direction.determinant() < 0);
    const std::string nii = tempPath("labels.nii.gz"), nrrd = tempPath("labels.nrrd");
    writeLabelImage(image, nii);
    writeLabelImage(image, nrrd);
    LabelImage a = readLabelImage(nii), b = readLabelImage(nrrd);
    QCOMPARE(a.format, std::string("NIfTI"));
    QCOMPARE(b.format, std::string("NRRD"));
    for (const LabelImage* x : {&a, &b}) {
      QCOMPARE(x->size, image.size);
      QVERIFY(x->labels == image.labels);
      QVERIFY((x->spacing - image.spacing).cwiseAbs().maxCoeff() < 1e-12);
      QVERIFY((x->origin - image.origin).cwiseAbs().maxCoeff() < 1e-9);
      QVERIFY((x->direction - image.direction).cwiseAbs().maxCoeff() < 1e-6);
      QCOMPARE(x->frame, std::string("LPS"));
    }
    LabelMeshOptions o;
    o.tetrahedralise.targetTets = 20000;
    const Mesh ma = meshLabelImage(a, o), mb = meshLabelImage(b, o);
    QCOMPARE(ma.tets.size(), mb.tets.size());
    QCOMPARE(ma.points.size(), mb.points.size());
    QVERIFY(ma.tets == mb.tets);
    QVERIFY(ma.tetLabels == mb.tetLabels);
    double worst = 0;
    for (std::size_t i = 0; i < ma.points.size(); ++i) worst = std::max(worst, (ma.points[i] - mb.points[i]).norm());
    qInfo("NIfTI vs NRRD: %zu tets each, largest node difference %.3g m", ma.tets.size(), worst);
    QVERIFY(worst < 1e-9);
    QCOMPARE(computeQuality(ma).inverted, std::size_t(0));
    // The tumour (label 2): its volume against the voxels and against 4/3 pi r^3, its centre where the direction
    // puts the voxel centre it was carved around.
    const auto counts = a.labelCounts();
    QVERIFY(counts.count(2));
    const auto volumes = labelVolumes(ma);
    for (const auto& [l, v] : volumes)
      qInfo("label %d: %.3f mL meshed, %ld voxels", l, v * 1e6, counts.count(l) ? counts.at(l) : 0L);
    QVERIFY2(volumes.count(2), "the tumour got no element");
    const double voxelVolume = static_cast<double>(counts.at(2)) * a.voxelVolume();
    const double sphere = 4.0 / 3.0 * std::numbers::pi * std::pow(r * 1e-3, 3);
    qInfo("tumour: meshed %.3f mL, voxels %.3f mL, sphere %.3f mL", volumes.at(2) * 1e6, voxelVolume * 1e6,
          sphere * 1e6);
    // Elements of about 15 mm here (20,000 over 3 L), as large as the tumour's radius: its polyhedron is 8.5 % short
    // of the voxels (the notes say so per label); 10 % bounds it.
    QVERIFY(std::abs(volumes.at(2) - voxelVolume) < 0.10 * voxelVolume);
    QVERIFY(std::abs(voxelVolume - sphere) < 0.05 * sphere);
    Eigen::Vector3d meshed = Eigen::Vector3d::Zero();
    double w = 0;
    for (std::size_t i = 0; i < ma.tets.size(); ++i)
      if (ma.tetLabels[i] == 2) {
        const auto& t = ma.tets[i];
        const double v = tetVolume(ma.points[t[0]], ma.points[t[1]], ma.points[t[2]], ma.points[t[3]]);
        meshed += v * (ma.points[t[0]] + ma.points[t[1]] + ma.points[t[2]] + ma.points[t[3]]) / 4.0;
        w += v;
      }
    meshed /= w;
    // Independent of the code: origin + D * (spacing * ijk) written out by hand for this direction.
    const Eigen::Vector3d ijkMm = centre.cwiseProduct(Eigen::Vector3d(0.75, 0.75, 1.5));
    const Eigen::Vector3d expected = Eigen::Vector3d(-120.5 + ijkMm.y(), 80.25 + ijkMm.x(), -310.0 + ijkMm.z()) * 1e-3;
    qInfo("tumour centre: meshed (%.2f, %.2f, %.2f) mm, expected (%.2f, %.2f, %.2f) mm", meshed.x() * 1e3,
          meshed.y() * 1e3, meshed.z() * 1e3, expected.x() * 1e3, expected.y() * 1e3, expected.z() * 1e3);
    QVERIFY((meshed - expected).norm() < 0.5e-3);
    // RAS: the same mesh with x and y negated.
    o.ras = true;
    const Mesh ras = meshLabelImage(a, o);
    QCOMPARE(ras.points.size(), ma.points.size());
    double rasWorst = 0;
    for (std::size_t i = 0; i < ras.points.size(); ++i)
      rasWorst = std::max(
          rasWorst, (ras.points[i] - Eigen::Vector3d(-ma.points[i].x(), -ma.points[i].y(), ma.points[i].z())).norm());
    QVERIFY(rasWorst < 1e-12);
    QCOMPARE(computeQuality(ras).inverted, std::size_t(0));
  }

  void colourTablesAndSlicerNames() {
    const auto slicer = parseColourTable(
        "# Color table file\n0 Background 0 0 0 0\n1 liver 221 130 101 255\n"
        "2 portal_vein 0 151 206 255\n7 tumour 1 2 3 255\nnot a line\n");
    QCOMPARE(slicer.size(), std::size_t(3));
    QCOMPARE(slicer.at(2), std::string("portal vein"));
    const auto snap = parseColourTable(
        "################################################\n# ITK-SnAP Label Description File\n"
        "    0     0    0    0        0  0  0    \"Clear Label\"\n"
        "    1   255    0    0        1  1  1    \"Liver #1\"\n"
        "    3     0    0  255        1  1  1    \"hepatic vein\"\n"
        "    4     0    0  255        1  1  1    \"unterminated\n");
    QCOMPARE(snap.size(), std::size_t(2));
    QCOMPARE(snap.at(1), std::string("Liver #1"));
    QCOMPARE(snap.at(3), std::string("hepatic vein"));
    // A table beside the image names the mesh's labels.
    LabelImage image;
    image.size = {6, 6, 6};
    image.spacing = Eigen::Vector3d::Constant(2e-3);
    image.labels.assign(216, 0);
    for (long k = 1; k < 5; ++k)
      for (long j = 1; j < 5; ++j)
        for (long i = 1; i < 5; ++i) image.labels[static_cast<std::size_t>(i + 6 * (j + 6 * k))] = i < 3 ? 1 : 3;
    const std::string path = tempPath("beside.nrrd");
    writeLabelImage(image, path);
    writeFile(tempPath("beside.ctbl"), "1 liver 1 2 3 255\n3 hepatic_vein 4 5 6 255\n");
    const LabelImage read = readLabelImage(path);
    QCOMPARE(read.names.at(1), std::string("liver"));
    QCOMPARE(read.names.at(3), std::string("hepatic vein"));
    LabelMeshOptions o;
    o.tetrahedralise.targetTets = 300;
    const Mesh m = meshLabelImage(read, o);
    QCOMPARE(m.labelName(3), std::string("hepatic vein"));
    QVERIFY(m.labelIsVessel(3));
    QVERIFY(!m.labelIsVessel(1));
    // 3D Slicer's .seg.nrrd header names segments (key:=value lines).
    std::string header =
        "NRRD0004\ntype: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: 4 4 4\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\nendian: little\nencoding: raw\n"
        "space origin: (0,0,0)\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=5\nSegment0_Name:=gallbladder\n\n";
    std::string voxels(64, '\0');
    voxels[21] = 5;
    writeFile(tempPath("seg.seg.nrrd"), header + voxels);
    const LabelImage seg = readLabelImage(tempPath("seg.seg.nrrd"));
    QCOMPARE(seg.names.at(5), std::string("gallbladder"));
  }

  // What a user might pick by mistake: one sentence each, before anything large is allocated.
  void badImagesGiveOneSentence() {
    checkOneSentence(errorOf([] { readLabelImage(tempPath("missing.nii.gz")); }), "no such file");
    writeFile(tempPath("x.stl"), "solid x\nendsolid x\n");
    checkOneSentence(errorOf([] { readLabelImage(tempPath("x.stl")); }), "not a label image");
    writeFile(tempPath("garbage.nii.gz"), std::string(5000, 'x'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("garbage.nii.gz")); }), "garbage.nii.gz");
    writeFile(tempPath("garbage.inr.gz"), std::string(5000, 'x'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("garbage.inr.gz")); }), "garbage.inr.gz");
    const std::string head = "NRRD0004\ndimension: 3\nencoding: raw\nendian: little\n";
    // Truncated voxels.
    writeFile(tempPath("short.nrrd"), head + "type: unsigned char\nsizes: 10 10 10\n\n" + std::string(100, '\1'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("short.nrrd")); }), "short.nrrd");
    // A CT, not labels.
    std::string floats(8 * 4, '\0');
    const float half = 0.5f;
    std::memcpy(&floats[4], &half, 4);
    writeFile(tempPath("ct.nrrd"), head + "type: float\nsizes: 2 2 2\n\n" + floats);
    checkOneSentence(errorOf([] { readLabelImage(tempPath("ct.nrrd")); }), "not whole numbers");
    // 2D, 4D and huge images.
    writeFile(tempPath("flat.nrrd"),
              "NRRD0004\ndimension: 2\nencoding: raw\ntype: unsigned char\nsizes: 4 4\n\n" + std::string(16, '\1'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("flat.nrrd")); }), "2D");
    writeFile(tempPath("layers.nrrd"),
              "NRRD0004\ndimension: 4\nencoding: raw\ntype: unsigned char\nsizes: 2 2 2 3\n\n" + std::string(24, '\1'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("layers.nrrd")); }), "layers");
    writeFile(tempPath("huge.nrrd"), head + "type: unsigned char\nsizes: 5000 5000 5000\n\n" + std::string(64, '\1'));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("huge.nrrd")); }), "million voxels");
    // Nothing labelled.
    LabelImage empty;
    empty.size = {3, 3, 3};
    empty.labels.assign(27, 0);
    writeLabelImage(empty, tempPath("empty.nii.gz"));
    checkOneSentence(errorOf([] { readLabelImage(tempPath("empty.nii.gz")); }), "no labelled voxel");
    // RAS asked of an image with no orientation; a label it does not have.
    if (std::filesystem::exists(sharedData(kLiver))) {
      const LabelImage inr = readLabelImage(sharedData(kLiver));
      LabelMeshOptions o;
      o.ras = true;
      checkOneSentence(errorOf([&] { meshLabelImage(inr, o); }), "no orientation");
      o.ras = false;
      o.only = {42};
      checkOneSentence(errorOf([&] { meshLabelImage(inr, o); }), "no voxel labelled 42");
    }
  }

  // Damaged files, as a disk or a copy leaves them: the headers of a NIfTI, an NRRD and a MetaImage written by ITK,
  // each mutated 1000 ways (MUTATIONS=N for more; a byte changed, a number made huge, the file cut short). Each read
  // either gives an image whose voxels fill its size with a positive spacing, or one sentence; no crash, no other
  // exception, and nothing over the voxel limit allocated (ASan and the limit's own check would say).
  void damagedHeadersNeverCrash() {
    LabelImage image;
    image.size = {9, 7, 5};
    image.spacing = Eigen::Vector3d(0.8, 0.8, 2.5) * 1e-3;
    image.origin = Eigen::Vector3d(-10, 20, 30) * 1e-3;
    image.labels.assign(9 * 7 * 5, 0);
    for (std::size_t i = 0; i < image.labels.size(); ++i)
      image.labels[i] = static_cast<std::int32_t>(i % 7 == 0 ? 3 : i % 5 == 0);
    std::uint64_t state = 0x9e3779b97f4a7c15ull;
    auto next = [&state] {
      state ^= state << 13;
      state ^= state >> 7;
      state ^= state << 17;
      return state;
    };
    // Two that kept ITK busy for minutes before the headers were checked first: a NIfTI whose sform holds 1.7e38 (its
    // SVD never returned) and a MetaImage with NDims = 399999999.
    {
      writeLabelImage(image, tempPath("sform.nii"));
      std::string b = readFile(tempPath("sform.nii"));
      const float huge = 1.7e38f;
      std::memcpy(&b[284], &huge, 4);  // srow_x[1] (NIfTI-1, little-endian as ITK writes it here)
      writeFile(tempPath("sform.nii"), b);
      checkOneSentence(errorOf([] { readLabelImage(tempPath("sform.nii")); }), "header is damaged");
      writeLabelImage(image, tempPath("ndims.mha"));
      b = readFile(tempPath("ndims.mha"));
      QVERIFY(b.find("NDims = 3") != std::string::npos);
      b.replace(b.find("NDims = 3"), 9, "NDims = 399999999");
      writeFile(tempPath("ndims.mha"), b);
      checkOneSentence(errorOf([] { readLabelImage(tempPath("ndims.mha")); }), "header is damaged");
      // Two the fuzzer found that made MetaIO ask for 2^63 bytes of compressed voxels: an ElementDataFile name ended
      // by a NUL byte with no '=' after it, and a data file name of control characters and NUL bytes.
      const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_UCHAR\nCompressedData = True\n";
      writeFile(tempPath("nodata.mha"), head + std::string("ElementDataFile\0NRRD0004\nLLLL\n", 30));
      checkOneSentence(errorOf([] { readLabelImage(tempPath("nodata.mha")); }), "no ElementDataFile field");
      writeFile(tempPath("controlname.mha"), head + std::string("ElementDataFile = \xff\xff\x0f\0\0\0\xffLOCALx\n", 32));
      checkOneSentence(errorOf([] { readLabelImage(tempPath("controlname.mha")); }), "not a file name");
    }
    const int kMutations =
        qEnvironmentVariableIntValue("MUTATIONS") > 0 ? qEnvironmentVariableIntValue("MUTATIONS") : 1000;
    for (const std::string ext : {".nii", ".nrrd", ".mha"}) {
      const std::string original = tempPath("intact" + ext), damaged = tempPath("damaged" + ext);
      writeLabelImage(image, original);
      const std::string bytes = readFile(original);
      QVERIFY(bytes.size() > 315);
      const std::size_t header = std::min<std::size_t>(400, bytes.size());  // the header and the first voxels
      int read = 0, refused = 0;
      for (int k = 0; k < kMutations; ++k) {
        std::string b = bytes;
        switch (k % 4) {
          case 0:  // one byte of the header changed
            b[next() % header] = static_cast<char>(next() & 0xff);
            break;
          case 1:  // a number made huge
            b.insert(next() % header, "99999999");
            break;
          case 2:  // cut short
            b.resize(next() % b.size());
            break;
          default:  // three bytes changed
            for (int j = 0; j < 3; ++j) b[next() % header] = static_cast<char>(next() & 0xff);
        }
        writeFile(damaged, b);
        try {
          const LabelImage got = readLabelImage(damaged);
          QCOMPARE(got.labels.size(), static_cast<std::size_t>(got.size[0] * got.size[1] * got.size[2]));
          QVERIFY(got.spacing.minCoeff() > 0 && got.spacing.allFinite());
          ++read;
        } catch (const MeshError& e) {
          const std::string what = e.what();
          QVERIFY2(!what.empty() && what.find('\n') == std::string::npos && what.size() < 400,
                   (ext + " mutation " + std::to_string(k) + ": " + what).c_str());
          ++refused;
        }
      }
      qInfo("%s: %d damaged copies, %d read, %d refused with one sentence", ext.c_str(), kMutations, read, refused);
      QVERIFY(refused > 0);
    }
  }


  // Issue 60, findings 8-13: headers and data that ITK's readers crash on (NRRD "dimension: 10" smashed the stack, a
  // MetaImage data-file pattern went to snprintf), follow (two billion data files), or read as garbage (NaN spacing
  // as 1 mm, truncated or undecodable voxels from uninitialised memory), and voxel sizes CGAL never finishes meshing.
  void hostileNrrd() {
    const std::string head = "NRRD0004\nencoding: raw\nendian: little\ntype: unsigned char\n";
    writeFile(tempPath("dim10.nrrd"), head + "dimension: 10\nsizes: 1 1 1 1 1 1 1 1 1 2\nspace origin: (0,0,0)\n\n" +
                                          std::string(2, '\1'));
    expectImageRefused("dim10.nrrd", "10 dimensions", true);
    writeFile(tempPath("nan.nrrd"), head + "dimension: 3\nsizes: 2 2 2\nspacings: nan 1 1\n\n" + std::string(8, '\1'));
    expectImageRefused("nan.nrrd", "not a number", true);
    writeFile(tempPath("nandir.nrrd"), head + "dimension: 3\nsizes: 2 2 2\nspace: left-posterior-superior\n"
                                              "space directions: (nan,0,0) (0,1,0) (0,0,1)\n\n" + std::string(8, '\1'));
    expectImageRefused("nandir.nrrd", "not a number");
    writeFile(tempPath("pattern.nhdr"), head + "dimension: 3\nsizes: 2 2 2\ndata file: slice%d.raw 0 2147483647 1\n");
    expectImageRefused("pattern.nhdr", "pattern", true);
    writeFile(tempPath("list.nhdr"), head + "dimension: 3\nsizes: 2 2 2\ndata file: LIST\na.raw\n");
    expectImageRefused("list.nhdr", "pattern");
    for (const char* spacing : {"1e300", "1e-300"}) {
      writeFile(tempPath("voxel.nrrd"), head + "dimension: 3\nsizes: 2 2 2\nspacings: " + spacing + " 1 1\n\n" + std::string(8, '\1'));
      expectImageRefused("voxel.nrrd", "voxel size of");
    }
    // The same header with sensible spacings is read.
    writeFile(tempPath("fine.nrrd"), head + "dimension: 3\nsizes: 2 2 2\nspacings: 0.5 0.5 2\n\n" + std::string(8, '\1'));
    QCOMPARE(readLabelImage(tempPath("fine.nrrd")).labelCounts().at(1), 8L);
  }
  void hostileMetaImage() {
    const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 9 7 5\nElementType = MET_UCHAR\n";
    writeFile(tempPath("format.mhd"), head + "ElementDataFile = %s%n%s%n%s%n.raw\n");
    expectImageRefused("format.mhd", "pattern", true);
    writeFile(tempPath("list.mhd"), head + "ElementDataFile = LIST\na.raw\n");
    expectImageRefused("list.mhd", "pattern");
    std::filesystem::create_directories(tempPath("voxels.d"));
    writeFile(tempPath("dir.mhd"), head + "ElementDataFile = voxels.d\n");
    expectImageRefused("dir.mhd", "not a file", true);
    // Uncompressed, 200 of 315 bytes.
    writeFile(tempPath("short.mha"), head + "ElementDataFile = LOCAL\n" + std::string(200, '\1'));
    expectImageRefused("short.mha", "truncated", true);
    writeFile(tempPath("whole.mha"), head + "ElementDataFile = LOCAL\n" + std::string(315, '\1'));
    QCOMPARE(readLabelImage(tempPath("whole.mha")).labelCounts().at(1), 315L);
    writeFile(tempPath("tiny.mha"), "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementSpacing = 1e-300 1 1\n"
                                    "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + std::string(8, '\1'));
    expectImageRefused("tiny.mha", "voxel size of");
    // ITK writes compressed MetaImages: cut short, and with garbage in place of the compressed data.
    writeLabelImage(smallImage(), tempPath("intact.mha"));
    const std::string bytes = readFile(tempPath("intact.mha"));
    QVERIFY(bytes.find("CompressedData = True") != std::string::npos);
    const std::size_t data = bytes.find("ElementDataFile = LOCAL\n") + 24;
    writeFile(tempPath("cut.mha"), bytes.substr(0, data + (bytes.size() - data) / 2));
    expectImageRefused("cut.mha", "cut.mha");
    std::string garbage = bytes;
    for (std::size_t i = data + 2; i < garbage.size(); ++i) garbage[i] = static_cast<char>(i * 7919 % 251);
    writeFile(tempPath("garbage.mha"), garbage);
    expectImageRefused("garbage.mha", "compressed data", true);
    // MetaIO allocates the CompressedDataSize it is given at once (the fuzzer's: 1e30 asked for 2^63 bytes, -5 for
    // 2^64 - 5), so a size that is not a number of bytes, or more bytes than the file holds, is refused first.
    const std::size_t field = bytes.find("CompressedDataSize = ");
    QVERIFY(field != std::string::npos && field < data);
    const std::size_t valueAt = field + 21, valueEnd = bytes.find('\n', valueAt);
    const long long written = std::stoll(bytes.substr(valueAt, valueEnd - valueAt));
    QCOMPARE(written, static_cast<long long>(bytes.size() - data));  // ITK's own size: what the file holds
    for (const std::string& value : std::vector<std::string>{"1e30", "-5", "0", "12.5", "7x", std::to_string(written + 1)}) {
      std::string b = bytes;
      b.replace(valueAt, valueEnd - valueAt, value);
      writeFile(tempPath("compressedsize.mha"), b);
      const std::string why = errorOf([] { readLabelImage(tempPath("compressedsize.mha")); });
      checkOneSentence(why, "CompressedDataSize");
      QVERIFY2(why.find("header is damaged") != std::string::npos, (value + ": " + why).c_str());
    }
    // MetaIO ends a field's name at a carriage return or a ':' as at '=', and takes the value after the next '=' or
    // ':' (the fuzzer's: "CompressedDataSize \r~= 1e30" asked for 2^63 bytes): the header is refused as damaged.
    for (const std::string& line : {std::string("CompressedDataSize \r~= 1e30"), std::string("CompressedDataSize\n= 1e30"),
                                    std::string("CompressedDataSize : 1e30")}) {
      std::string b = bytes;
      b.replace(field, valueEnd - field, line);
      writeFile(tempPath("separator.mha"), b);
      const std::string why = errorOf([] { readLabelImage(tempPath("separator.mha")); });
      checkOneSentence(why, "header is damaged");
    }
    QCOMPARE(readLabelImage(tempPath("intact.mha")).labels, smallImage().labels);
  }
  void hostileNifti() {
    writeLabelImage(smallImage(), tempPath("intact.nii"));
    const std::string bytes = readFile(tempPath("intact.nii"));
    float voxOffset = 0;
    std::memcpy(&voxOffset, &bytes[108], 4);
    QVERIFY(voxOffset >= 348 && bytes.size() >= voxOffset + 315);
    // 20 % and 99.9 % of the voxels' bytes (ITK writes them as unsigned char here or wider: measured from the file).
    const double dataBytes = static_cast<double>(bytes.size()) - voxOffset;
    for (double share : {0.2, 0.999}) {
      const std::string cut = bytes.substr(0, static_cast<std::size_t>(voxOffset + share * dataBytes));
      writeFile(tempPath("cut.nii"), cut);
      expectImageRefused("cut.nii", "truncated", share < 0.5);
      gzipped(cut, tempPath("cut.nii.gz"));
      expectImageRefused("cut.nii.gz", "truncated");
    }
    for (float offset : {1e12f, -100.f, std::nanf("")}) {
      std::string b = bytes;
      std::memcpy(&b[108], &offset, 4);
      writeFile(tempPath("offset.nii"), b);
      expectImageRefused("offset.nii", "not in the file");
      gzipped(b, tempPath("offset.nii.gz"));
      expectImageRefused("offset.nii.gz", "not in the file");
    }
    // Voxel sizes of 1e-30 mm and 1000 mm (pixdim[1], a float at byte 80).
    for (float size : {1e-30f, 1000.f}) {
      std::string b = bytes;
      std::memcpy(&b[80], &size, 4);
      writeFile(tempPath("pixdim.nii"), b);
      expectImageRefused("pixdim.nii", "voxel size of");
    }
    gzipped(bytes, tempPath("whole.nii.gz"));
    QCOMPARE(readLabelImage(tempPath("whole.nii.gz")).labels, smallImage().labels);
    QCOMPARE(readLabelImage(tempPath("intact.nii")).labels, smallImage().labels);
  }
  // Found by fuzzing the readers (scripts/fuzz.sh, fuzz_images): a NIfTI whose header size field is neither 348 nor
  // 540 was still read by ITK's NIfTI library, unchecked, and a NaN in its sform aborted ITK's SVD (SIGABRT); a
  // MetaImage field name of 400 characters overflowed MetaIO's 255-byte name (SIGABRT from glibc's fortify); a .inr
  // holding a PGM went to CGAL's PNM reader, which never returned at the end of the file.
  void fuzzFindingsAreRefused() {
    writeLabelImage(smallImage(), tempPath("sized.nii"));
    std::string nifti = readFile(tempPath("sized.nii"));
    const std::int32_t oddSize = 16220;
    std::memcpy(&nifti[0], &oddSize, 4);
    const float nan = std::nanf("");
    std::memcpy(&nifti[280 + 11 * 4], &nan, 4);  // srow_z[3]
    writeFile(tempPath("oddsize.nii"), nifti);
    expectImageRefused("oddsize.nii", "not a NIfTI image", true);
    // The NIfTI library takes the byte order from dim[0] when it is not 0: a size field of 348 in this order with a
    // dim[0] of 3 only in the other (bytes 00 03) was read swapped, its swapped pixdim NaN, and ITK's SVD aborted.
    std::string swapped = readFile(tempPath("sized.nii"));
    swapped[40] = '\0', swapped[41] = '\3';
    const char bigEndianNan[4] = {'\x7f', '\xc0', '\0', '\0'};
    std::memcpy(&swapped[80], bigEndianNan, 4);  // pixdim[1], as the swapped reading sees it
    writeFile(tempPath("dim0swapped.nii"), swapped);
    expectImageRefused("dim0swapped.nii", "header is damaged", true);
    swapped[40] = '\x09', swapped[41] = '\x09';  // 2313 either way
    writeFile(tempPath("dim0bad.nii"), swapped);
    expectImageRefused("dim0bad.nii", "not 1 to 7 in either byte order", true);
    writeFile(tempPath("short.nii"), nifti.substr(0, 100));
    expectImageRefused("short.nii", "fewer than a NIfTI header", true);
    const std::string longName(300, 'x');
    writeFile(tempPath("longname.mha"), "ObjectType = Image\nNDims = 3\n" + longName +
                                            " = 1\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                                            "ElementDataFile = LOCAL\n" + std::string(8, '\1'));
    expectImageRefused("longname.mha", "field name of", true);
    // A name run across lines without an '=' (MetaIO reads up to the next '=') counts as one name.
    std::string spread;
    for (int i = 0; i < 30; ++i) spread += "abcdefghij\n";
    writeFile(tempPath("spread.mha"), "ObjectType = Image\nNDims = 3\n" + spread +
                                          "DimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                                          std::string(8, '\1'));
    expectImageRefused("spread.mha", "field name of", true);
    // MetaIO's field name is a C string: "NDims", a NUL and bytes after it is NDims (MetaIO read 1.6e18 values).
    writeFile(tempPath("nulname.mha"), "ObjectType = Image\nNDims" + std::string(2, '\0') +
                                           "`\x80X = 1605389506728077994\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                                           "ElementDataFile = LOCAL\n" + std::string(8, '\1'));
    expectImageRefused("nulname.mha", "NDims", true);
    // ... and a field given twice is refused: MetaIO read "NDims = 1.6e18" before the "NDims = 3" this check kept.
    writeFile(tempPath("twice.mha"), "ObjectType = Image\nNDims = 1605389506728077994\nDimSize = 2 2 2\n"
                                     "NDims = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                                         std::string(8, '\1'));
    expectImageRefused("twice.mha", "given twice", true);
    // A long value: MetaIO strcpy'd a 256-byte ObjectType into its 255 bytes (found by fuzzing: glibc's fortify aborted).
    writeFile(tempPath("longvalue.mha"), "ObjectType = Ima" + std::string(250, '\xff') +
                                             "ge\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                                             "ElementDataFile = LOCAL\n" + std::string(8, '\1'));
    expectImageRefused("longvalue.mha", "a value of 255 characters for its field 'ObjectType'", true);
    writeFile(tempPath("pgm.inr"), "P5\n2 2\n255\n");
    expectImageRefused("pgm.inr", "not an INR image", true);
    // The same shapes, sound, are read: a MetaImage with a short unknown field, and the NIfTI as ITK wrote it.
    writeFile(tempPath("extra.mha"), "ObjectType = Image\nNDims = 3\nComment = from a scanner\nDimSize = 2 2 2\n"
                                         "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + std::string(8, '\1'));
    QCOMPARE(readLabelImage(tempPath("extra.mha")).labelCounts().at(1), 8L);
    QCOMPARE(readLabelImage(tempPath("sized.nii")).labels, smallImage().labels);
  }
  void hostileInrVoxelSize() {
    for (const char* vx : {"1e300", "1e-300"}) {
      std::string h = std::string("#INRIMAGE-4#{\nXDIM=2\nYDIM=2\nZDIM=2\nVDIM=1\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n"
                                  "CPU=decm\nVX=") + vx + "\nVY=1\nVZ=1\n";
      h += std::string(252 - h.size(), '\n') + "##}\n";
      writeFile(tempPath("voxel.inr"), h + std::string(8, '\1'));
      expectImageRefused("voxel.inr", "voxel size of", true);
    }
  }
  // Finding 13: the colour table's size is checked before it is read (a 3 GiB sparse file, refused at once).
  void hugeColourTable() {
    writeLabelImage(smallImage(), tempPath("tabled.nii.gz"));
    writeFile(tempPath("tabled.ctbl"), "1 one 0 0 0 255\n");
    std::filesystem::resize_file(tempPath("tabled.ctbl"), std::uintmax_t(3) << 30);
    QElapsedTimer t;
    t.start();
    checkOneSentence(errorOf([] { readLabelImage(tempPath("tabled.nii.gz")); }), "over 16 MB");
    QVERIFY2(t.elapsed() < 2000, qPrintable(QString("%1 ms").arg(t.elapsed())));
    std::filesystem::remove(tempPath("tabled.ctbl"));
  }

  void cancelStopsMeshing() {
    REQUIRE_SHARED(kLiver);
    const LabelImage image = readLabelImage(sharedData(kLiver));
    std::atomic<bool> cancel{false};
    LabelMeshOptions o;
    o.tetrahedralise.targetTets = 20000;
    o.tetrahedralise.cancel = &cancel;
    int calls = 0;
    o.tetrahedralise.progress = [&](double, const std::string&) {
      if (++calls == 2) cancel = true;
    };
    bool cancelled = false;
    try {
      meshLabelImage(image, o);
    } catch (const Cancelled&) {
      cancelled = true;
    }
    QVERIFY(cancelled);
    QVERIFY(calls >= 2);
  }
};

QTEST_GUILESS_MAIN(TestLabelImage)
#include "test_labelimage.moc"
