// Case files (SQLite through Qt SQL): every field survives save and reopen; killing the program
// during a save never corrupts the last saved case; damaged files and parts give clear messages.
#include <rehearse/app/recording.hpp>
#include "test_support.hpp"

#include "phantom/phantom.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "box_mesh.hpp"

#include <rehearse/simcore/precomputed.hpp>

#include <malloc.h>

#include <QDir>
#include <QFile>
#include <QProcess>
#include <QStandardPaths>
#include <QSqlDatabase>
#include <QSqlQuery>
#include <QSqlError>
#include <QCryptographicHash>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <optional>
#include <random>

using namespace rehearse;

namespace {
const app::Case& phantomCase() {
  static const app::Case c = app::caseFromPhantom(phantom::makePhantom());
  return c;
}

void compareCases(const app::Case& a, const app::Case& b) {
  QCOMPARE(QString::fromStdString(b.name), QString::fromStdString(a.name));
  QCOMPARE(b.organ->volume.points.size(), a.organ->volume.points.size());
  for (std::size_t i = 0; i < a.organ->volume.points.size(); ++i) QCOMPARE(b.organ->volume.points[i], a.organ->volume.points[i]);
  QVERIFY(b.organ->volume.tets == a.organ->volume.tets);
  QVERIFY(b.organ->volume.tetLabels == a.organ->volume.tetLabels);
  QVERIFY(b.organ->volume.labelNames == a.organ->volume.labelNames);
  QVERIFY(b.organ->surface == a.organ->surface);
  QVERIFY(b.attachments == a.attachments);
  QCOMPARE(b.camera.K, a.camera.K);
  QVERIFY(b.camera.distortion == a.camera.distortion);
  QCOMPARE(b.camera.width, a.camera.width);
  QCOMPARE(b.camera.height, a.camera.height);
  QCOMPARE(cv::norm(b.frame, a.frame, cv::NORM_INF), 0.0);
  QCOMPARE(b.groundTruth != nullptr, a.groundTruth != nullptr);
  QCOMPARE(b.groundTruth->pose.R, a.groundTruth->pose.R);
  QCOMPARE(b.groundTruth->pose.t, a.groundTruth->pose.t);
  QCOMPARE(b.groundTruth->appearance.kd, a.groundTruth->appearance.kd);
  QCOMPARE(b.groundTruth->appearance.ks, a.groundTruth->appearance.ks);
  QCOMPARE(b.groundTruth->appearance.lightPosition, a.groundTruth->appearance.lightPosition);
  QCOMPARE(b.groundTruth->appearance.roughness, a.groundTruth->appearance.roughness);
  QCOMPARE(b.groundTruth->vesselAxes.size(), a.groundTruth->vesselAxes.size());
  QCOMPARE(b.hasPose, a.hasPose);
  QCOMPARE(b.poseAligned, a.poseAligned);
  QVERIFY((b.down - a.down).norm() < 1e-15);
  QCOMPARE(b.pose.R, a.pose.R);
  QCOMPARE(b.pose.t, a.pose.t);
  QCOMPARE(b.contour.width, a.contour.width);
  QCOMPARE(b.contour.segments.size(), a.contour.segments.size());
  for (std::size_t s = 0; s < a.contour.segments.size(); ++s) {
    QVERIFY(b.contour.segments[s].points == a.contour.segments[s].points);
    QCOMPARE(b.contour.segments[s].closed, a.contour.segments[s].closed);
    QCOMPARE(b.contour.segments[s].type, a.contour.segments[s].type);
    QVERIFY(b.contour.segments[s].modelVertices == a.contour.segments[s].modelVertices);
  }
}

// Runs SQL statements on a case file directly (as damage on disk or an older writer leaves it): the first value of the
// last statement's first row (an invalid QVariant when it has none); nothing when the file or a statement fails.
std::optional<QVariant> sqlOn(const QString& path, const QStringList& statements) {
  std::optional<QVariant> out;
  {
    auto db = QSqlDatabase::addDatabase("QSQLITE", "direct");
    db.setDatabaseName(path);
    if (db.open()) {
      QSqlQuery q(db);
      bool ok = true;
      for (const QString& sql : statements) ok = ok && q.exec(sql);
      if (ok) out = q.next() ? q.value(0) : QVariant();
      if (!ok) qWarning("%s", qPrintable(q.lastError().text()));
    }
    db.close();
  }
  QSqlDatabase::removeDatabase("direct");
  return out;
}
}  // namespace

class TestCaseFile : public QObject {
  Q_OBJECT
 private slots:
  // Undo memory: 200 pose edits (one drag each) of a 20k-tet organ with a 1280x720 frame hold less than one
  // more case: the organ, the frame and the fit are shared between undo states. Measured as the heap in
  // use (glibc's mallinfo2), not by the code's own byte counter.
  void undoStatesShareTheOrgan() {
    auto heap = [] {
      malloc_trim(0);
      const auto m = mallinfo2();
      return static_cast<double>(m.uordblks + m.hblkhd);  // small blocks in use + large (mmapped) ones
    };
    const double start = heap();
    ui::CaseDocument doc;
    {
      app::Case c;
      c.name = "memory";
      c.organ = app::Organ::fromVolume(boxMesh(0.12, 0.10, 0.08, 15, 15, 15));
      c.camera = imaging::Camera::defaultFor(1280, 720);
      c.frame = cv::Mat3b(720, 1280, cv::Vec3b(40, 60, 160));
      c.pose = c.automaticPose();
      c.hasPose = true;
      QCOMPARE(c.organ->volume.tets.size(), std::size_t(20250));
      doc.setVersion(std::make_shared<const app::Case>(std::move(c)));
    }
    const double oneCase = heap() - start;
    for (int i = 0; i < 200; ++i)
      doc.edit(QStringLiteral("Move"), [i](app::Case& k) { k.pose.t.x() += 1e-4 * (i + 1); }, -1);
    QCOMPARE(doc.undoStack()->count(), 200);
    const double all = heap() - start;
    qInfo("one case %.1f MB; with 200 pose edits on its undo stack %.1f MB (%.3fx, %.1f kB per edit)", oneCase / 1e6, all / 1e6, all / oneCase,
          (all - oneCase) / 200 / 1e3);
    QVERIFY(oneCase > 1e6);
    QVERIFY(all < 2 * oneCase);
  }

  // The first automatic placement keeps any organ inside the image: wide, tall (a 16:9 image is lower than
  // wide) and deep ones (the near side is closer than the centre), checked by projecting every node.
  void automaticPlacementKeepsTheOrganInTheImage() {
    struct Shape {
      const char* name;
      double x, y, z;
    };
    for (const Shape& sh : {Shape{"wide", 0.30, 0.10, 0.06}, Shape{"tall", 0.10, 0.22, 0.06}, Shape{"deep", 0.12, 0.12, 0.30},
                            Shape{"large", 0.25, 0.20, 0.18}}) {
      app::Case c;
      c.organ = app::Organ::fromVolume(boxMesh(sh.x, sh.y, sh.z, 6, 6, 6));
      c.camera = imaging::Camera::defaultFor(1280, 720);
      c.pose = c.automaticPose();
      Eigen::AlignedBox2d box;
      double nearest = 1e9;
      for (const auto& x : c.organ->volume.points) {
        const Eigen::Vector3d xc = c.pose.apply(x);
        nearest = std::min(nearest, xc.z());
        if (xc.z() > 0) box.extend(c.camera.project(xc));
      }
      qInfo("%-5s organ %.0f x %.0f x %.0f mm: centre at %.0f mm, nearest node %.0f mm; spans u %.0f..%.0f, v %.0f..%.0f px", sh.name,
            1e3 * sh.x, 1e3 * sh.y, 1e3 * sh.z, 1e3 * c.pose.apply(c.organ->centreOfGravity).z(), 1e3 * nearest, box.min().x(), box.max().x(),
            box.min().y(), box.max().y());
      QVERIFY(nearest > 0.01);
      QVERIFY2(box.min().x() >= 0 && box.max().x() <= 1280 && box.min().y() >= 0 && box.max().y() <= 720, sh.name);
      QVERIFY2(box.sizes().maxCoeff() > 0.3 * 720, sh.name);  // not a dot either
    }
  }

  void saveAndReopenEveryField() {
    const QString path = QString::fromStdString(tempPath("phantom.rehearse"));
    app::Case edited = phantomCase();
    edited.contour.width = 1280;
    edited.contour.height = 720;
    edited.contour.segments.push_back({{{100.25, 200.5}, {300, 400}, {512.125, 333}}, false, "silhouette", {}});
    edited.contour.segments.push_back({{{10, 20}, {30, 40}}, true, "ridge", {3, 7, 11}});
    edited.pose.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
    edited.pose.t = {0.0123, -0.004, 0.21};
    edited.poseAligned = true;
    edited.down = Eigen::Vector3d(0.6, 0.8, 0);
    edited.material.supportModulus = 2.5e4;
    edited.material.gravity = app::GravityChoice::DownInTheImage;  // issue 61: a stated choice of the case
    {
      auto organ = std::make_shared<app::Organ>(*edited.organ);
      organ->sourceUnitToMetre = 0.001;  // imported from a file in mm
      // Its own surface (issue 35): here its boundary, each triangle split in three at its centroid (points the
      // volume's nodes do not have), carried by the tetrahedra.
      simcore::Mesh own;
      own.points = organ->volume.points;
      for (const auto& t : organ->surface) {
        const int c = static_cast<int>(own.points.size());
        own.points.push_back((own.points[t[0]] + own.points[t[1]] + own.points[t[2]]) / 3);
        own.triangles.push_back({t[0], t[1], c});
        own.triangles.push_back({t[1], t[2], c});
        own.triangles.push_back({t[2], t[0], c});
      }
      own.triangleLabels.assign(own.triangles.size(), 1);
      std::string why;
      organ->visual = app::VisualSurface::make(organ->volume, own, &why);
      QVERIFY2(organ->visual, why.c_str());
      edited.organ = organ;
    }
    ui::saveCaseFile(edited, path);
    QVERIFY(ui::isCaseFile(path));
    QStringList notes;
    auto back = ui::loadCaseFile(path, &notes);
    QVERIFY2(notes.isEmpty(), qPrintable(notes.join('\n')));
    compareCases(edited, back);
    QVERIFY(back.material == edited.material);
    QCOMPARE(back.material.gravity, app::GravityChoice::DownInTheImage);
    QCOMPARE(back.organ->sourceUnitToMetre, 0.001);
    QVERIFY(back.organ->visual);
    QCOMPARE(back.organ->visual->triangles, edited.organ->visual->triangles);
    QCOMPARE(back.organ->visual->points.size(), edited.organ->visual->points.size());
    double moved = 0;
    for (std::size_t i = 0; i < back.organ->visual->points.size(); ++i)
      moved = std::max(moved, (back.organ->visual->points[i] - edited.organ->visual->points[i]).norm());
    QVERIFY(moved < 1e-12);
    QCOMPARE(back.organ->visual->map(back.organ->volume.points).size(), back.organ->visual->points.size());
    // Saving again over it replaces it whole and leaves no temporary file behind.
    ui::saveCaseFile(back, path);
    QCOMPARE(QDir(QFileInfo(path).absolutePath()).entryList({"phantom.rehearse.saving-*"}).size(), 0);
  }

  // A rehearsal recorded into the case file survives the case being saved again (the save writes a new file
  // and renames it over the old one): listed, and its recorded states still replay bit for bit.
  void recordedRehearsalsSurviveSaving() {
    const QString path = QString::fromStdString(tempPath("recorded.rehearse"));
    ui::saveCaseFile(phantomCase(), path);
    simcore::BodySetup s;  // one tetrahedron hanging from three fixed nodes
    s.mesh.points = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}, {0, 0, 0.01}};
    s.mesh.tets = {{0, 1, 2, 3}};
    s.mesh.tetLabels = {1};
    s.fixedNodes = {0, 1, 2};
    s.settings.method = simcore::NewtonMethod::Exact;
    std::int64_t id = 0;
    {
      app::Recorder rec(QFile::encodeName(path).toStdString(), {"trainee", "phantom", "v1", "test", "", ""}, s, 5, 8);
      simcore::Session session(s);
      session.setStepHook([&rec](const simcore::StepRecord& r) { rec.afterStep(r); });
      for (long k = 1; k <= 20; ++k) session.advance();
      QCOMPARE(rec.checkpoints(), 2L);  // after steps 8 and 16
      rec.finish(20);
      id = rec.id();
    }
    ui::saveCaseFile(ui::loadCaseFile(path), path, path);  // saved over itself: the recordings come from the file it lives in
    const auto sessions = app::listRecordings(QFile::encodeName(path).toStdString());
    QCOMPARE(sessions.size(), std::size_t(1));
    QCOMPARE(sessions.front().uuid.size(), std::size_t(32));
    QCOMPARE(sessions.front().meta.trainee, std::string("trainee"));
    const auto v = app::verifyRecording(app::loadRecording(QFile::encodeName(path).toStdString(), id));
    QCOMPARE(v.checked, 4L);
    QCOMPARE(v.mismatches, 0L);
    // Its checkpoints came along: seeking to step 19 starts from the one after step 16 and lands on the
    // recorded state (the checksum recorded after step 15 and 20 bracket it: compare at 20).
    const auto rec = app::loadRecording(QFile::encodeName(path).toStdString(), id);
    QCOMPARE(rec.checkpointSteps, (std::vector<long>{8, 16}));
    app::Replayer replayer(rec);
    replayer.seek(20);
    QCOMPARE(replayer.lastSeekFrom(), 16L);
    QCOMPARE(app::stateChecksum(replayer.state()), rec.checksums.at(20));
    compareCases(phantomCase(), ui::loadCaseFile(path));
    // Save As to another file carries them (with their identity); a file saved over with no source holds none of
    // the target's old sessions (the target is replaced, not merged).
    const QString other = QString::fromStdString(tempPath("recorded-as.rehearse"));
    ui::saveCaseFile(ui::loadCaseFile(path), other, path);
    const auto carried = app::listRecordings(QFile::encodeName(other).toStdString());
    QCOMPARE(carried.size(), std::size_t(1));
    QCOMPARE(carried.front().uuid, sessions.front().uuid);
    QCOMPARE(app::verifyRecording(app::loadRecording(QFile::encodeName(other).toStdString(), carried.front().id)).mismatches, 0L);
    ui::saveCaseFile(phantomCase(), other);
    QVERIFY(app::listRecordings(QFile::encodeName(other).toStdString()).empty());
  }

  // A child process saves in a loop and is killed with SIGKILL at random moments; each time the file
  // on disk must open whole and equal to the case.
  void killDuringSaveNeverCorrupts_data() {
    QTest::addColumn<QString>("path");
    QTest::addColumn<int>("rounds");
    QTest::newRow("save") << QString::fromStdString(tempPath("killed.rehearse")) << 12;
    // The autosave goes through the same atomic write, to the application's data folder.
    QStandardPaths::setTestModeEnabled(true);
    QTest::newRow("autosave") << ui::MainWindow::autosavePath() << 6;
  }
  void killDuringSaveNeverCorrupts() {
    QFETCH(QString, path);
    QFETCH(int, rounds);
    QDir().mkpath(QFileInfo(path).absolutePath());
    // The child saves the very case the parent wrote (read back from this file), so the comparison
    // does not depend on two processes generating the phantom identically.
    const QString source = QString::fromStdString(tempPath("kill-source.rehearse"));
    ui::saveCaseFile(phantomCase(), source);
    const app::Case expected = ui::loadCaseFile(source);
    ui::saveCaseFile(phantomCase(), path);
    QElapsedTimer saveTimer;
    saveTimer.start();
    ui::saveCaseFile(phantomCase(), path);
    const qint64 saveMs = saveTimer.elapsed();
    std::mt19937 rng(7);
    int kills = 0, midSave = 0;
    const QDir dir(QFileInfo(path).absolutePath());
    for (int round = 0; round < rounds; ++round) {
      QProcess child;
      child.start(QCoreApplication::applicationFilePath(), {"--save-loop", source, path});
      QVERIFY(child.waitForStarted());
      // Wait until the child has built its case and is saving (slow on a loaded machine), then kill it
      // after a random number of save durations.
      QVERIFY(child.waitForReadyRead(120000));
      QTest::qWait(static_cast<int>(std::max<qint64>(saveMs, 10) * (1 + rng() % 40) / 4));
      child.kill();  // SIGKILL
      child.waitForFinished();
      ++kills;
      midSave += dir.entryList({QFileInfo(path).fileName() + ".saving-*"}).size() > 0;
      QStringList notes;
      auto back = ui::loadCaseFile(path, &notes);
      QVERIFY2(notes.isEmpty(), qPrintable(notes.join('\n')));
      compareCases(expected, back);
      if (QTest::currentTestFailed()) return;
    }
    qInfo("one save takes %lld ms; killed the saving process %d times, %d of them in the middle of a save "
          "(a half-written temporary file was left); the case opened whole every time", saveMs, kills, midSave);
    QVERIFY(midSave >= kills / 2);  // the test really interrupts saves
    ui::saveCaseFile(phantomCase(), path);  // the next save clears the leftovers of killed ones
    QCOMPARE(dir.entryList({QFileInfo(path).fileName() + ".saving-*"}).size(), 0);
    if (path == ui::MainWindow::autosavePath()) {
      QVERIFY(ui::MainWindow::hasRecoverableAutosave());  // what the next start offers back
      QFile::remove(path);
    }
  }

  void corruptFilesGiveClearMessages() {
    const QString path = QString::fromStdString(tempPath("corrupt.rehearse"));
    writeFile(path.toStdString(), "this is not a database");
    try {
      ui::loadCaseFile(path);
      QFAIL("garbage accepted");
    } catch (const std::runtime_error& e) {
      QVERIFY2(QString(e.what()).contains("not a Rehearse case file"), e.what());
    }
    // A valid case truncated in the middle: SQLite reports corruption; we give one sentence.
    ui::saveCaseFile(phantomCase(), path);
    std::string bytes = readFile(path.toStdString());
    writeFile(path.toStdString(), bytes.substr(0, bytes.size() / 3));
    try {
      // If SQLite still opens the first pages, every part that is missing or damaged is reported in a note.
      QStringList notes;
      const auto c = ui::loadCaseFile(path, &notes);
      const bool whole = !c.organ->empty() && !c.frame.empty() && c.camera.width > 0;
      QVERIFY2(!whole || notes.isEmpty(), "a whole case with notes");
      QVERIFY2(whole || !notes.isEmpty(), "parts went missing without a note");
      for (const auto& n : notes) QCOMPARE(n.count('\n'), 0);
    } catch (const std::runtime_error& e) {
      QVERIFY(!QString(e.what()).isEmpty());
      QVERIFY(!QString(e.what()).contains('\n'));
    }
    QVERIFY_THROWS_EXCEPTION(std::runtime_error, ui::loadCaseFile(QString::fromStdString(tempPath("missing.rehearse"))));
  }

  // Damage anywhere in the file (SQLite's pages, the parts' bytes, their checksums): one byte at a time
  // at 200 places spread over the file. Each load opens the case (whole, or with a note for the part
  // that was hit) or refuses it with one sentence; it never crashes and never hangs.
  void randomDamageNeverCrashes() {
    const QString clean = QString::fromStdString(tempPath("undamaged.rehearse"));
    ui::saveCaseFile(phantomCase(), clean);
    const std::string bytes = readFile(clean.toStdString());
    std::mt19937 rng(2026);
    std::uniform_int_distribution<std::size_t> where(0, bytes.size() - 1);
    std::uniform_int_distribution<int> value(1, 255);
    int whole = 0, noted = 0, refused = 0;
    const QString path = QString::fromStdString(tempPath("damaged-byte.rehearse"));
    for (int i = 0; i < 200; ++i) {
      std::string damaged = bytes;
      const std::size_t at = i < 100 ? where(rng) % std::min<std::size_t>(bytes.size(), 16384) : where(rng);  // the header pages too
      damaged[at] = static_cast<char>(damaged[at] ^ value(rng));
      writeFile(path.toStdString(), damaged);
      try {
        QStringList notes;
        const app::Case c = ui::loadCaseFile(path, &notes);
        if (notes.isEmpty()) ++whole;
        else ++noted;
        for (const auto& n : notes) QVERIFY2(!n.contains('\n'), qPrintable(n));
      } catch (const std::exception& e) {
        ++refused;
        QVERIFY2(!QString(e.what()).trimmed().isEmpty() && !QString(e.what()).trimmed().contains('\n'), e.what());
      }
    }
    qInfo("200 single-byte damages of a %zu-byte case file: %d opened whole (bytes SQLite or the parts do not use), "
          "%d opened with a note for the damaged part, %d refused with one sentence",
          bytes.size(), whole, noted, refused);
    QCOMPARE(whole + noted + refused, 200);
    QVERIFY(noted > 0);  // most of the file is the parts' data, covered by their checksums
  }

  void damagedPartLeavesTheRestIntact() {
    const QString path = QString::fromStdString(tempPath("damaged-part.rehearse"));
    ui::saveCaseFile(phantomCase(), path);
    {
      auto db = QSqlDatabase::addDatabase("QSQLITE", "damage");
      db.setDatabaseName(path);
      QVERIFY(db.open());
      QSqlQuery q(db);
      // The volume's garbage comes with a matching checksum (as a faulty writer would leave it: the
      // decoder must refuse it); the frame's bytes change under their old checksum (damage on disk).
      q.prepare("UPDATE parts SET data = ?, sha256 = ? WHERE name = 'volume'");
      q.addBindValue(QByteArray::fromHex("00112233"));
      q.addBindValue(QCryptographicHash::hash(QByteArray::fromHex("00112233"), QCryptographicHash::Sha256));
      QVERIFY(q.exec());
      QVERIFY(q.exec("UPDATE parts SET data = X'89504E47' WHERE name = 'frame'"));
      db.close();
    }
    QSqlDatabase::removeDatabase("damage");
    QStringList notes;
    auto c = ui::loadCaseFile(path, &notes);
    QCOMPARE(notes.size(), 3);  // mesh, frame, and attachments that now refer to missing nodes
    QVERIFY(notes[0].startsWith("Organ mesh not loaded"));
    QVERIFY(notes[1].startsWith("Frame not loaded"));
    QVERIFY2(notes[1].contains("checksum"), qPrintable(notes[1]));
    QVERIFY2(!notes[0].contains("checksum"), qPrintable(notes[0]));
    QCOMPARE(c.camera.K, phantomCase().camera.K);
    QVERIFY(c.groundTruth != nullptr);
  }

  // A case's gravity that is none of the panel's choices is refused with a sentence (the material falls back to its
  // defaults, the rest of the case opens); a case saved before gravity was stored opens with it into the scene.
  void aCaseGravityIsOneOfThePanelsChoices() {
    const QString path = QString::fromStdString(tempPath("gravity.rehearse"));
    for (const char* gravity : {"sideways", ""}) {
      app::Case c = phantomCase();
      c.material.gravity = app::GravityChoice::Off;
      c.material.young = 12e3;
      ui::saveCaseFile(c, path);
      {
        auto db = QSqlDatabase::addDatabase("QSQLITE", "gravity");
        db.setDatabaseName(path);
        QVERIFY(db.open());
        QSqlQuery q(db);
        QVERIFY(q.exec("SELECT data FROM parts WHERE name = 'material'") && q.next());
        nlohmann::json j = nlohmann::json::parse(q.value(0).toByteArray().toStdString());
        if (*gravity)
          j["gravity"] = gravity;
        else
          j.erase("gravity");
        const QByteArray bytes = QByteArray::fromStdString(j.dump());
        q.prepare("UPDATE parts SET data = ?, sha256 = ? WHERE name = 'material'");
        q.addBindValue(bytes);
        q.addBindValue(QCryptographicHash::hash(bytes, QCryptographicHash::Sha256));
        QVERIFY(q.exec());
        db.close();
      }
      QSqlDatabase::removeDatabase("gravity");
      QStringList notes;
      const app::Case back = ui::loadCaseFile(path, &notes);
      qInfo("gravity '%s': %s", gravity, qPrintable(notes.join(" | ")));
      if (*gravity) {
        QCOMPARE(notes.size(), 1);
        QVERIFY2(notes[0].contains("gravity is not one of"), qPrintable(notes[0]));
      } else {
        QVERIFY2(notes.isEmpty(), qPrintable(notes.join(" | ")));
        QCOMPARE(back.material.gravity, app::GravityChoice::IntoTheScene);
        QCOMPARE(back.material.young, 12e3);
      }
    }
  }

  // The precomputed model's responses (issue 37) are kept with the case: saved under their key, offered back to the
  // response cache when the case opens (byte for byte), read by a body of the same organ to the same numbers; damaged
  // on disk they are dropped with a note; a key the cache does not hold saves nothing.
  void precomputedResponsesAreKept() {
    const app::Case& c = phantomCase();
    simcore::Mesh mesh = c.organ->volume;
    mesh.convertToMetres();
    simcore::MaterialParams m;
    m.model = simcore::MaterialModel::Linear;
    const simcore::FemModel model = simcore::FemModel::build(mesh, {}, m);
    std::vector<char> fixed(model.nodeCount(), 0);
    for (int v : c.attachments) fixed[static_cast<std::size_t>(v)] = 1;
    std::vector<int> driven;
    for (const auto& t : c.organ->surface)
      for (int v : t)
        if (!fixed[static_cast<std::size_t>(v)] && std::find(driven.begin(), driven.end(), v) == driven.end())
          driven.push_back(v);
    std::uint64_t key = 0;
    std::string from, why;
    auto& cache = simcore::ResponseCache::shared();
    cache.clear();
    const auto built = simcore::precomputedFor(model, fixed, driven, Eigen::Vector3d(0, 9.81, 0), {}, key, from, why);
    QVERIFY2(built, why.c_str());
    const QString path = QString::fromStdString(tempPath("responses.rehearse"));
    ui::saveCaseFile(c, path, {}, key);
    cache.clear();
    QStringList notes;
    ui::loadCaseFile(path, &notes);
    QVERIFY2(notes.isEmpty(), qPrintable(notes.join(" | ")));
    const auto stored = cache.storedBytes(key);
    QVERIFY(stored);
    QVERIFY(*stored == built->toBytes());
    const auto again = simcore::precomputedFor(model, fixed, driven, Eigen::Vector3d(0, 9.81, 0), {}, key, from, why);
    QCOMPARE(from, std::string("case file"));
    Eigen::VectorXd u1, u2;
    const std::vector<Eigen::Vector3d> d{Eigen::Vector3d(0.01, 0, 0)};
    QVERIFY(built->solve({driven[0]}, d, u1, nullptr, why) && again->solve({driven[0]}, d, u2, nullptr, why));
    QVERIFY(u1 == u2);
    QVERIFY(sqlOn(path, {"UPDATE parts SET data = substr(data, 1, 64) WHERE name = 'precomputed_responses'"}));
    cache.clear();
    notes.clear();
    ui::loadCaseFile(path, &notes);
    QCOMPARE(notes.size(), 1);
    QVERIFY2(notes[0].startsWith("Precomputed responses not loaded") && notes[0].contains("checksum"),
             qPrintable(notes[0]));
    QVERIFY(!cache.storedBytes(key));
    ui::saveCaseFile(c, path, {}, key + 1);  // not in the cache: nothing kept
    const auto kept = sqlOn(path, {"SELECT count(*) FROM parts WHERE name = 'precomputed_responses'"});
    QVERIFY(kept && kept->isValid());
    QCOMPARE(kept->toInt(), 0);
    cache.clear();
  }

  // A case saved with schema 1 (no checksum column, no elastic fit part) opens whole, and saving it again
  // writes schema 2.
  void schemaOneIsMigrated() {
    const QString path = QString::fromStdString(tempPath("schema1.rehearse"));
    app::Case edited = phantomCase();
    edited.contour.segments.push_back({{{100.25, 200.5}, {300, 400}, {512.125, 333}}, false, "silhouette", {}});
    ui::saveCaseFile(edited, path);
    QVERIFY(sqlOn(path, {"UPDATE meta SET value = '1' WHERE key = 'schema_version'",
                         "ALTER TABLE parts DROP COLUMN sha256", "DELETE FROM parts WHERE name = 'elastic_fit'"}));
    QStringList notes;
    const auto back = ui::loadCaseFile(path, &notes);
    QVERIFY2(notes.isEmpty(), qPrintable(notes.join('\n')));
    compareCases(edited, back);
    ui::saveCaseFile(back, path);
    {
      auto db = QSqlDatabase::addDatabase("QSQLITE", "new");
      db.setDatabaseName(path);
      QVERIFY(db.open());
      QSqlQuery q(db);
      QVERIFY(q.exec("SELECT value FROM meta WHERE key = 'schema_version'") && q.next());
      QCOMPARE(q.value(0).toInt(), ui::kCaseSchemaVersion);
      QVERIFY(q.exec("SELECT COUNT(*) FROM parts WHERE length(sha256) = 32") && q.next());
      QVERIFY(q.value(0).toInt() >= 5);
      db.close();
    }
    QSqlDatabase::removeDatabase("new");
    compareCases(edited, ui::loadCaseFile(path));
  }

  void newerSchemaIsRefusedClearly() {
    const QString path = QString::fromStdString(tempPath("future.rehearse"));
    ui::saveCaseFile(phantomCase(), path);
    QVERIFY(sqlOn(path, {"UPDATE meta SET value = '99' WHERE key = 'schema_version'"}));
    try {
      ui::loadCaseFile(path);
      QFAIL("a newer schema was accepted");
    } catch (const std::runtime_error& e) {
      QVERIFY2(QString(e.what()).contains("newer Rehearse"), e.what());
    }
  }

  // A save that cannot complete leaves the previous file byte for byte: after a first save, a folder stands
  // where the new file is written before it replaces the old one (works as root too, unlike permissions).
  void unwritableTargetKeepsPreviousFile() {
    const std::string dir = tempPath("blocked-case");
    std::filesystem::create_directories(dir);
    const QString path = QString::fromStdString(dir + "/case.rehearse");
    ui::saveCaseFile(phantomCase(), path);
    const std::string before = readFile(path.toStdString());
    QVERIFY(before.size() > 1000);
    const QString blocker = path + QStringLiteral(".saving-") + QString::number(QCoreApplication::applicationPid());
    QVERIFY(QDir().mkpath(blocker));
    QFile(blocker + "/keep").open(QIODevice::WriteOnly);  // not an empty folder: it cannot be removed as a file
    app::Case changed = phantomCase();
    changed.name = "changed";
    try {
      ui::saveCaseFile(changed, path);
      QFAIL("the save reported success although its file could not be written");
    } catch (const std::runtime_error& e) {
      qInfo("refused: %s", e.what());
      QVERIFY(!QString(e.what()).contains('\n'));
    }
    QCOMPARE(readFile(path.toStdString()), before);
    QCOMPARE(QString::fromStdString(ui::loadCaseFile(path).name), QString::fromStdString(phantomCase().name));
    QDir(blocker).removeRecursively();
    // A folder that does not exist: said in our words, not SQLite's ("unable to open database file").
    try {
      ui::saveCaseFile(phantomCase(), QString::fromStdString(tempPath("nowhere/sub/case.rehearse")));
      QFAIL("saved into a folder that does not exist");
    } catch (const std::runtime_error& e) {
      qInfo("refused: %s", e.what());
      QVERIFY2(QString(e.what()).contains("cannot be created there") && !QString(e.what()).contains("unable to open"), e.what());
    }
  }
};

int main(int argc, char** argv) {
  QCoreApplication app(argc, argv);
  if (argc == 4 && QByteArray(argv[1]) == "--save-loop") {
    // Child mode for killDuringSaveNeverCorrupts: save the given case forever until killed.
    const app::Case c = ui::loadCaseFile(QString::fromLocal8Bit(argv[2]));
    std::fputs("ready\n", stdout);
    std::fflush(stdout);
    for (;;) ui::saveCaseFile(c, QString::fromLocal8Bit(argv[3]));
  }
  QStandardPaths::setTestModeEnabled(true);
  TestCaseFile t;
  return QTest::qExec(&t, argc, argv);
}
#include "test_casefile.moc"
