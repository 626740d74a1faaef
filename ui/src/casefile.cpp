#include "rehearse/ui/casefile.hpp"

#include <rehearse/app/recording.hpp>

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/app/materials.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/precomputed.hpp>

#include <QCoreApplication>
#include <QCryptographicHash>
#include <QDateTime>
#include <QFile>
#include <QFileInfo>
#include <QSqlDatabase>
#include <QSqlError>
#include <QSqlQuery>
#include <QUuid>
#include <QVariant>

#include <rehearse/app/incorrect_actions.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>

#include <QDir>

#include <cerrno>
#include <cmath>
#include <csignal>

#include <fcntl.h>
#include <unistd.h>

using nlohmann::json;

namespace rehearse::ui {
namespace {

[[noreturn]] void fail(const QString& message) { throw std::runtime_error(message.toStdString()); }

// A uniquely named connection that is removed when the scope ends.
class Connection {
 public:
  explicit Connection(const QString& file) : name_(QUuid::createUuid().toString()) {
    db_ = QSqlDatabase::addDatabase(QStringLiteral("QSQLITE"), name_);
    db_.setDatabaseName(file);
  }
  ~Connection() {
    db_.close();
    db_ = QSqlDatabase();
    QSqlDatabase::removeDatabase(name_);
  }
  QSqlDatabase& db() { return db_; }

 private:
  QString name_;
  QSqlDatabase db_;
};

json poseJson(const Pose& p) {
  return {{"R", {{p.R(0, 0), p.R(0, 1), p.R(0, 2)}, {p.R(1, 0), p.R(1, 1), p.R(1, 2)}, {p.R(2, 0), p.R(2, 1), p.R(2, 2)}}},
          {"t", {p.t.x(), p.t.y(), p.t.z()}},
          {"unit", "m"}};
}
Pose poseFrom(const json& j) {
  Pose p;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) p.R(r, k) = j.at("R").at(r).at(k).get<double>();
    p.t[r] = j.at("t").at(r).get<double>();
  }
  return p;
}
json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec3(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

void fsyncFile(const QString& path) {
  const int fd = ::open(QFile::encodeName(path).constData(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

void fsyncDirectoryOf(const QString& path) {
  const int fd = ::open(QFile::encodeName(QFileInfo(path).absolutePath()).constData(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}


// Why SQLite failed, in our words (its own text, e.g. "unable to open database file Error opening
// database", names no cause a user can act on). The codes are SQLite's primary result codes.
QString sqlProblem(const QSqlError& e) {
  bool ok = false;
  const int code = e.nativeErrorCode().toInt(&ok) & 0xff;
  if (!ok) return QStringLiteral("the database reported an error");
  switch (code) {
    case 13: return QStringLiteral("the disk is full");                              // SQLITE_FULL
    case 8: case 3: return QStringLiteral("the folder or file is read-only");       // SQLITE_READONLY, SQLITE_PERM
    case 14: return QStringLiteral("the file cannot be created there (a folder missing or not writable)");  // SQLITE_CANTOPEN
    case 10: return QStringLiteral("the disk reported an input/output error");       // SQLITE_IOERR
    case 11: case 26: return QStringLiteral("the file is damaged or not a database"); // SQLITE_CORRUPT, SQLITE_NOTADB
    case 5: case 6: return QStringLiteral("another program holds the file");         // SQLITE_BUSY, SQLITE_LOCKED
    default: return QStringLiteral("the database reported error %1").arg(code);
  }
}
// The case file's words for where gravity points (material.json's "gravity").
const char* gravityWord(app::GravityChoice g) {
  switch (g) {
    case app::GravityChoice::DownInTheImage:
      return "down in the image";
    case app::GravityChoice::Off:
      return "off";
    case app::GravityChoice::IntoTheScene:
      break;
  }
  return "into the scene";
}

}  // namespace

bool isCaseFile(const QString& path) {
  if (path.isEmpty() || !QFileInfo(path).isFile()) return false;
  QFile f(path);
  if (!f.open(QIODevice::ReadOnly)) return false;
  return f.read(16) == QByteArray("SQLite format 3\0", 16);
}

// SQLite's blobs stop at 1 GB: the precomputed responses are kept with the case up to half that.
constexpr std::size_t kMaxStoredResponses = std::size_t(512) << 20;

void saveCaseFile(const app::Case& c, const QString& path, const QString& recordingsFrom, std::uint64_t responseKey) {
  const QString tmp = path + QStringLiteral(".saving-") + QString::number(QCoreApplication::applicationPid());
  QFile::remove(tmp);
  {
    Connection conn(tmp);
    auto& db = conn.db();
    if (!db.open()) fail(QStringLiteral("Cannot write %1: %2; choose another folder.").arg(path, sqlProblem(db.lastError())));
    QSqlQuery q(db);
    // The temporary file is renamed only once complete, so the journal can stay in memory.
    q.exec(QStringLiteral("PRAGMA journal_mode=OFF"));
    q.exec(QStringLiteral("PRAGMA synchronous=OFF"));
    if (!q.exec(QStringLiteral("CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)")) ||
        !q.exec(QStringLiteral("CREATE TABLE parts(name TEXT PRIMARY KEY, format TEXT NOT NULL, data BLOB NOT NULL, sha256 BLOB NOT NULL, "
                               "saved_utc TEXT NOT NULL)")))
      fail(QStringLiteral("Cannot write %1: %2.").arg(path, sqlProblem(q.lastError())));
    db.transaction();
    const QString now = QDateTime::currentDateTimeUtc().toString(Qt::ISODateWithMs);
    auto meta = [&](const QString& k, const QString& v) {
      QSqlQuery m(db);
      m.prepare(QStringLiteral("INSERT INTO meta(key, value) VALUES(?, ?)"));
      m.addBindValue(k);
      m.addBindValue(v);
      if (!m.exec()) fail(QStringLiteral("Cannot write %1: %2.").arg(path, sqlProblem(m.lastError())));
    };
    meta(QStringLiteral("schema_version"), QString::number(kCaseSchemaVersion));
    meta(QStringLiteral("app_version"), QStringLiteral(REHEARSE_VERSION));
    meta(QStringLiteral("name"), QString::fromStdString(c.name));
    meta(QStringLiteral("saved_utc"), now);
    auto part = [&](const char* name, const char* format, const QByteArray& data) {
      QSqlQuery p(db);
      p.prepare(QStringLiteral("INSERT INTO parts(name, format, data, sha256, saved_utc) VALUES(?, ?, ?, ?, ?)"));
      p.addBindValue(QString::fromLatin1(name));
      p.addBindValue(QString::fromLatin1(format));
      p.addBindValue(data);
      p.addBindValue(QCryptographicHash::hash(data, QCryptographicHash::Sha256));
      p.addBindValue(now);
      if (!p.exec()) fail(QStringLiteral("Cannot write %1: %2.").arg(path, sqlProblem(p.lastError())));
    };
    auto bytes = [](const std::string& s) { return QByteArray(s.data(), static_cast<qsizetype>(s.size())); };
    const simcore::Mesh& volume = c.organ->volume;
    if (!volume.empty()) {
      part("volume", "vtu", bytes(simcore::writeVtu(volume, false)));
      json labels = json::array();
      for (const auto& [l, n] : volume.labelNames) labels.push_back({{"label", l}, {"name", n}});
      part("labels", "json", bytes(labels.dump()));
      if (const auto& visual = c.organ->visual) {  // the organ's own surface (its embedding is remade on loading)
        simcore::Mesh surface;
        surface.points = visual->points;
        surface.triangles = visual->triangles;
        part("visual_surface", "vtu", bytes(simcore::writeVtu(surface, false)));
      }
    }
    if (!c.frame.empty()) {
      std::vector<uchar> png;
      cv::imencode(".png", c.frame, png);
      part("frame", "png", QByteArray(reinterpret_cast<const char*>(png.data()), static_cast<qsizetype>(png.size())));
    }
    if (!c.rawFrame.empty() && c.rawFrame.data != c.frame.data) {
      std::vector<uchar> png;
      cv::imencode(".png", c.rawFrame, png);
      part("raw_frame", "png", QByteArray(reinterpret_cast<const char*>(png.data()), static_cast<qsizetype>(png.size())));
    }
    if (c.camera.width > 0) {
      const auto& k = c.camera;
      json cam = {{"K", {{k.K(0, 0), k.K(0, 1), k.K(0, 2)}, {k.K(1, 0), k.K(1, 1), k.K(1, 2)}, {k.K(2, 0), k.K(2, 1), k.K(2, 2)}}},
                  {"distortion", k.distortion},
                  {"width", k.width},
                  {"height", k.height}};
      if (c.down.norm() > 0) cam["down"] = {c.down.x(), c.down.y(), c.down.z()};
      part("camera", "json", bytes(cam.dump()));
    }
    part("attachments", "json", bytes(json{{"nodes", c.attachments}}.dump()));
    if (c.hasPose) part("pose", "json", bytes(json{{"pose", poseJson(c.pose)}, {"aligned", c.poseAligned}}.dump()));
    if (!c.organ->source.empty()) meta(QStringLiteral("mesh_source"), QString::fromStdString(c.organ->source));
    meta(QStringLiteral("mesh_source_unit_m"), QString::number(c.organ->sourceUnitToMetre, 'g', 17));
    {
      const auto& m = c.material;
      part("material", "json",
           bytes(json{{"model", simcore::toString(m.model)},
                      {"young", m.young},
                      {"poisson", m.poisson},
                      {"density", m.density},
                      {"vessel_young", m.vesselYoung},
                      {"vessel_poisson", m.vesselPoisson},
                      {"tear_strain", m.tearStrain},
                      {"support_modulus", m.supportModulus},
                      {"gravity", gravityWord(m.gravity)}}
                     .dump()));
    }
    if (!c.incorrectActions.empty()) part("incorrect_actions", "json", bytes(c.incorrectActions));
    if (!c.contour.segments.empty()) part("contour", "json", bytes(imaging::contourToJson(c.contour)));
    if (!c.frame2.empty()) {  // the second frame (issue 38), its outline and how far the scope moved
      std::vector<uchar> png;
      cv::imencode(".png", c.frame2, png);
      part("second_frame", "png",
           QByteArray(reinterpret_cast<const char*>(png.data()), static_cast<qsizetype>(png.size())));
      part("second_frame_move", "json", bytes(json{{"baseline_mm", c.baselineMm}}.dump()));
      if (!c.contour2.segments.empty()) part("second_contour", "json", bytes(imaging::contourToJson(c.contour2)));
    }
    if (!c.landmarks.empty()) {
      json pairs = json::array();
      for (const auto& l : c.landmarks)
        pairs.push_back({{"model", {l.model.x(), l.model.y(), l.model.z()}}, {"image", {l.image.x(), l.image.y()}}, {"has_image", l.hasImage}});
      part("landmarks", "json", bytes(json{{"pairs", pairs}, {"unit", "m (model), px (image)"}}.dump()));
    }
    if (c.fit) {
      json pts = json::array();
      for (const auto& x : c.fit->nodes) pts.push_back({x.x(), x.y(), x.z()});
      part("elastic_fit", "json", bytes(json{{"positions", pts}, {"status", c.fit->status}}.dump()));
    }
    if (c.appearance) part("appearance", "json", bytes(app::appearanceEstimateToJson(*c.appearance)));
    if (c.groundTruth) {
      const app::GroundTruth& t = *c.groundTruth;
      json tree = json::array();
      for (std::size_t i = 0; i < t.vesselAxes.size(); ++i)
        tree.push_back({{"a", vec(t.vesselAxes[i].first)}, {"b", vec(t.vesselAxes[i].second)}, {"radius", t.vesselRadii[i]}});
      const auto& a = t.appearance;
      json gt = {{"pose", poseJson(t.pose)},
                 {"appearance",
                  {{"light_position", vec(a.lightPosition)},
                   {"kd", vec(a.kd)},
                   {"ks", vec(a.ks)},
                   {"roughness", a.roughness},
                   {"falloff", a.falloff}}},
                 {"vessel_tree", tree}};
      part("ground_truth", "json", bytes(gt.dump()));
    }
    if (responseKey != 0)
      if (const auto r = simcore::ResponseCache::shared().find(responseKey);
          r && r->memoryBytes() <= kMaxStoredResponses) {  // (larger ones are built again when the case opens)
        QByteArray data(reinterpret_cast<const char*>(&responseKey), sizeof responseKey);
        data += bytes(r->toBytes());
        part("precomputed_responses", "bin", data);
      }
    if (!db.commit()) fail(QStringLiteral("Cannot write %1: %2.").arg(path, sqlProblem(db.lastError())));
  }
  // Rehearsals recorded into the case (issue 16) are carried into the new file.
  if (!recordingsFrom.isEmpty() && isCaseFile(recordingsFrom)) {
    try {
      app::copyRecordings(QFile::encodeName(recordingsFrom).toStdString(), QFile::encodeName(tmp).toStdString());
    } catch (const std::runtime_error& e) {
      QFile::remove(tmp);
      fail(QStringLiteral("Cannot save %1: %2. The previous file is unchanged.").arg(path, QString::fromStdString(e.what())));
    }
  }
  fsyncFile(tmp);
  if (::rename(QFile::encodeName(tmp).constData(), QFile::encodeName(path).constData()) != 0) {
    QFile::remove(tmp);
    fail(QStringLiteral("Cannot replace %1; check that the folder is writable. The previous file is unchanged.").arg(path));
  }
  fsyncDirectoryOf(path);
  // Temporary files left by saves that were killed (their process is gone) are removed.
  const QFileInfo target(path);
  const QString prefix = target.fileName() + QStringLiteral(".saving-");
  for (const QFileInfo& f : QDir(target.absolutePath()).entryInfoList({prefix + QStringLiteral("*")}, QDir::Files)) {
    bool ok = false;
    const qint64 pid = f.fileName().mid(prefix.size()).toLongLong(&ok);
    if (ok && pid != QCoreApplication::applicationPid() && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
      QFile::remove(f.absoluteFilePath());
  }
}

app::Case loadCaseFile(const QString& path, QStringList* notes) {
  const QString name = QFileInfo(path).fileName();
  if (!QFileInfo::exists(path)) fail(QStringLiteral("The case file %1 does not exist; check the path.").arg(path));
  if (!isCaseFile(path)) fail(QStringLiteral("%1 is not a Rehearse case file (it is not an SQLite database).").arg(name));
  Connection conn(path);
  auto& db = conn.db();
  db.setConnectOptions(QStringLiteral("QSQLITE_OPEN_READONLY"));
  if (!db.open()) fail(QStringLiteral("%1 cannot be opened: %2.").arg(name, sqlProblem(db.lastError())));
  QSqlQuery q(db);
  if (!q.exec(QStringLiteral("SELECT value FROM meta WHERE key = 'schema_version'")) || !q.next())
    fail(QStringLiteral("%1 is damaged or not a Rehearse case (no schema version).").arg(name));
  const int version = q.value(0).toInt();
  if (version < 1) fail(QStringLiteral("%1 has an unknown schema version.").arg(name));
  if (version > kCaseSchemaVersion)
    fail(QStringLiteral("%1 was saved by a newer Rehearse (schema %2, this one reads up to %3); update Rehearse to open it.")
             .arg(name).arg(version).arg(kCaseSchemaVersion));
  // Migrations: schema 1 has no checksums (its parts are read as they are); the parts it lacks are simply
  // absent. Nothing is written back: the next save writes the current schema.
  const bool checksums = version >= 2;
  app::Case c;
  if (q.exec(QStringLiteral("SELECT value FROM meta WHERE key = 'name'")) && q.next()) c.name = q.value(0).toString().toStdString();
  auto note = [&](const QString& s) {
    if (notes) *notes << s;
  };
  // What each part is called in messages ("<what> not loaded: ...").
  const std::map<std::string, QString> partName = {{"volume", QStringLiteral("Organ mesh")},
                                                   {"labels", QStringLiteral("Organ labels")},
                                                   {"frame", QStringLiteral("Frame")},
                                                   {"raw_frame", QStringLiteral("Captured frame")},
                                                   {"camera", QStringLiteral("Camera")},
                                                   {"attachments", QStringLiteral("Attachments")},
                                                   {"pose", QStringLiteral("Pose")},
                                                   {"contour", QStringLiteral("Contour")},
                                                   {"second_frame", QStringLiteral("Second frame")},
                                                   {"second_frame_move", QStringLiteral("Second frame's move")},
                                                   {"second_contour", QStringLiteral("Second frame's contour")},
                                                   {"elastic_fit", QStringLiteral("Elastic fit")},
                                                   {"ground_truth", QStringLiteral("Ground truth")},
                                                   {"landmarks", QStringLiteral("Landmark pairs")},
                                                   {"appearance", QStringLiteral("Appearance")},
                                                   {"visual_surface", QStringLiteral("Organ surface")},
                                                   {"precomputed_responses", QStringLiteral("Precomputed responses")}};
  auto read = [&](const char* part) -> QByteArray {
    QSqlQuery p(db);
    p.prepare(checksums ? QStringLiteral("SELECT data, sha256 FROM parts WHERE name = ?") : QStringLiteral("SELECT data FROM parts WHERE name = ?"));
    p.addBindValue(QString::fromLatin1(part));
    const auto named = partName.find(part);
    const QString what = named != partName.end() ? named->second : QString::fromLatin1(part);
    if (!p.exec()) {
      note(QStringLiteral("%1 not loaded: it could not be read (%2).").arg(what, sqlProblem(p.lastError())));
      return {};
    }
    if (!p.next()) return {};
    QByteArray data = p.value(0).toByteArray();
    if (checksums && QCryptographicHash::hash(data, QCryptographicHash::Sha256) != p.value(1).toByteArray()) {
      note(QStringLiteral("%1 not loaded: the stored data is damaged (it no longer matches its checksum).").arg(what));
      return {};
    }
    return data;
  };
  if (QByteArray r = read("precomputed_responses"); r.size() > static_cast<qsizetype>(sizeof(std::uint64_t))) {
    std::uint64_t key = 0;
    std::memcpy(&key, r.constData(), sizeof key);
    simcore::ResponseCache::shared().offerBytes(
        key, std::make_shared<const std::string>(r.constData() + sizeof key, r.size() - sizeof key));
  }
  if (QByteArray v = read("volume"); !v.isEmpty()) {
    try {
      simcore::Mesh volume = simcore::parseVtu(std::string_view(v.constData(), static_cast<std::size_t>(v.size())));
      simcore::validateMesh(volume, "the organ mesh");
      if (QByteArray l = read("labels"); !l.isEmpty())
        for (const auto& e : json::parse(l.toStdString())) volume.setLabelName(e.at("label").get<int>(), e.at("name").get<std::string>());
      // The organ's own surface, drawn in the composited view: without it (older files, or damaged) the
      // simulation mesh's boundary is drawn, and the note says so.
      simcore::Mesh visual;
      if (QByteArray vs = read("visual_surface"); !vs.isEmpty()) {
        try {
          visual = simcore::parseVtu(std::string_view(vs.constData(), static_cast<std::size_t>(vs.size())));
          simcore::validateMesh(visual, "the organ's surface");
        } catch (const std::exception& e) {
          visual = {};
          note(QStringLiteral("Organ surface not loaded: %1 The simulation mesh's boundary is drawn instead.")
                   .arg(QString::fromUtf8(e.what())));
        }
      }
      std::string why;
      c.organ = app::Organ::fromVolume(std::move(volume), {}, 1.0, visual.triangles.empty() ? nullptr : &visual, &why);
      if (!why.empty()) note(QStringLiteral("Organ surface not used: %1").arg(QString::fromStdString(why)));
    } catch (const std::exception& e) {
      c.organ = std::make_shared<app::Organ>();
      note(QStringLiteral("Organ mesh not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray f = read("frame"); !f.isEmpty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.frame = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.frame.empty()) note(QStringLiteral("Frame not loaded: the stored image is damaged."));
  }
  if (QByteArray f = read("raw_frame"); !f.isEmpty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.rawFrame = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.rawFrame.empty()) note(QStringLiteral("Captured frame not loaded: the stored image is damaged."));
  }
  if (QByteArray k = read("camera"); !k.isEmpty()) {
    try {
      auto j = json::parse(k.toStdString());
      for (int r = 0; r < 3; ++r)
        for (int col = 0; col < 3; ++col) c.camera.K(r, col) = j.at("K").at(r).at(col).get<double>();
      for (int i = 0; i < 5; ++i) c.camera.distortion[i] = j.at("distortion").at(i).get<double>();
      c.camera.width = j.at("width").get<int>();
      c.camera.height = j.at("height").get<int>();
      if (auto p = c.camera.problem(); !p.empty()) throw std::runtime_error(p);
    } catch (const std::exception& e) {
      c.camera = {};
      note(QStringLiteral("Camera not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
    try {  // which way is down, told on the fit page (its own part of the camera's record)
      const auto j = json::parse(k.toStdString());
      if (j.contains("down")) {
        const Eigen::Vector3d d(j.at("down").at(0).get<double>(), j.at("down").at(1).get<double>(), j.at("down").at(2).get<double>());
        if (!(d.allFinite() && d.norm() > 0.5 && d.norm() < 2)) throw std::runtime_error("it is not a direction");
        c.down = d.normalized();
      }
    } catch (const std::exception& e) {
      c.down.setZero();
      note(QStringLiteral("Which way is down not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (c.camera.width == 0 && !c.frame.empty()) c.camera = imaging::Camera::defaultFor(c.frame.cols, c.frame.rows);
  if (QByteArray a = read("attachments"); !a.isEmpty()) {
    try {
      const json j = json::parse(a.toStdString());
      for (const auto& n : j.at("nodes")) {
        const int v = n.get<int>();
        if (v < 0 || v >= static_cast<int>(c.organ->volume.points.size())) throw std::out_of_range("node index out of range");
        c.attachments.push_back(v);
      }
    } catch (const std::exception& e) {
      c.attachments.clear();
      note(QStringLiteral("Attachments not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray p = read("pose"); !p.isEmpty()) {
    try {
      const json j = json::parse(p.toStdString());
      c.pose = poseFrom(j.at("pose"));
      c.poseAligned = j.value("aligned", false);
      c.hasPose = true;
    } catch (const std::exception& e) {
      note(QStringLiteral("Pose not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (!c.hasPose && !c.organ->empty()) {
    c.pose = c.automaticPose();
    c.hasPose = true;
  }
  if (!c.organ->empty()) {
    auto organ = std::make_shared<app::Organ>(*c.organ);  // once, while loading
    if (q.exec(QStringLiteral("SELECT value FROM meta WHERE key = 'mesh_source'")) && q.next()) organ->source = q.value(0).toString().toStdString();
    if (q.exec(QStringLiteral("SELECT value FROM meta WHERE key = 'mesh_source_unit_m'")) && q.next()) {
      bool ok = false;
      const double unit = q.value(0).toDouble(&ok);
      if (ok && unit > 0 && std::isfinite(unit)) organ->sourceUnitToMetre = unit;  // absent in older files: metres
    }
    c.organ = organ;
  }
  if (QByteArray m = read("material"); !m.isEmpty()) {
    try {
      const json j = json::parse(m.toStdString());
      app::MaterialSettings s;
      s.model = simcore::materialModelFromString(j.at("model").get<std::string>());
      s.young = j.at("young").get<double>();
      s.poisson = j.at("poisson").get<double>();
      s.density = j.at("density").get<double>();
      s.vesselYoung = j.value("vessel_young", 0.0);
      s.vesselPoisson = j.value("vessel_poisson", 0.45);
      s.tearStrain = j.value("tear_strain", 0.0);
      if (!(s.tearStrain >= 0 && s.tearStrain <= 10)) throw std::runtime_error("its tear strain is outside [0, 10]");
      s.supportModulus = j.value("support_modulus", s.supportModulus);  // (cases saved before it: the default)
      if (!(s.supportModulus >= 0 && s.supportModulus <= 1e9))
        throw std::runtime_error("its support modulus is outside [0, 1e9] Pa/m");
      if (j.contains("gravity")) {  // (cases saved before it: into the scene)
        const json& g = j.at("gravity");
        bool known = false;
        for (const auto choice : {app::GravityChoice::IntoTheScene, app::GravityChoice::DownInTheImage,
                                  app::GravityChoice::Off})
          if (g.is_string() && g.get<std::string>() == gravityWord(choice)) s.gravity = choice, known = true;
        if (!known)
          throw std::runtime_error("its gravity is not one of \"into the scene\", \"down in the image\" or \"off\"");
      }
      c.material = s;
    } catch (const std::exception& e) {
      note(QStringLiteral("Material not loaded (the default is used): %1").arg(QString::fromUtf8(e.what())));
    }
  } else if (!c.organ->empty()) {
    c.material = app::defaultMaterial(*c.organ);  // cases saved before the material was part of them
  }
  if (QByteArray r = read("incorrect_actions"); !r.isEmpty()) {
    try {
      app::parseActionRules(r.toStdString());
      c.incorrectActions = r.toStdString();
    } catch (const std::exception& e) {
      note(QStringLiteral("The trainer's incorrect-action rules were not loaded (the defaults are used): %1")
               .arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray k = read("contour"); !k.isEmpty()) {
    try {
      c.contour = imaging::parseContour(k.toStdString(), "the case's contour");
    } catch (const std::exception& e) {
      c.contour = {};
      note(QStringLiteral("Contour not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray f = read("second_frame"); !f.isEmpty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.frame2 = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.frame2.empty()) note(QStringLiteral("Second frame not loaded: the stored image is damaged."));
  }
  if (QByteArray k = read("second_frame_move"); !k.isEmpty() && !c.frame2.empty()) {
    try {
      c.baselineMm = json::parse(k.toStdString()).at("baseline_mm").get<double>();
      if (!(c.baselineMm >= 0 && c.baselineMm < 1e4)) throw std::runtime_error("not a distance in mm");
    } catch (const std::exception& e) {
      c.baselineMm = 0;
      note(QStringLiteral("Second frame's move not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray k = read("second_contour"); !k.isEmpty() && !c.frame2.empty()) {
    try {
      c.contour2 = imaging::parseContour(k.toStdString(), "the second frame's contour");
    } catch (const std::exception& e) {
      c.contour2 = {};
      note(QStringLiteral("Second frame's contour not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray l = read("landmarks"); !l.isEmpty()) {
    try {
      const json j = json::parse(l.toStdString());
      for (const auto& p : j.at("pairs")) {
        app::LandmarkPair pair;
        pair.model = vec3(p.at("model"));
        pair.image = {p.at("image").at(0).get<double>(), p.at("image").at(1).get<double>()};
        pair.hasImage = p.at("has_image").get<bool>();
        if (!pair.model.allFinite() || !pair.image.allFinite()) throw std::runtime_error("a pair holds a number that is not finite");
        c.landmarks.push_back(pair);
      }
    } catch (const std::exception& e) {
      c.landmarks.clear();
      note(QStringLiteral("Landmark pairs not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray f = read("elastic_fit"); !f.isEmpty()) {
    try {
      const json j = json::parse(f.toStdString());
      auto fit = std::make_shared<app::ElasticFit>();
      for (const auto& p : j.at("positions")) fit->nodes.emplace_back(p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>());
      fit->status = j.value("status", std::string());
      if (fit->nodes.size() != c.organ->volume.points.size()) throw std::runtime_error("it does not match the organ mesh");
      c.fit = fit;
    } catch (const std::exception& e) {
      note(QStringLiteral("Elastic fit not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray a = read("appearance"); !a.isEmpty()) {
    try {
      c.appearance = app::appearanceEstimateFromJson(a.toStdString());
    } catch (const std::exception& e) {
      note(QStringLiteral("Appearance not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  if (QByteArray g = read("ground_truth"); !g.isEmpty()) {
    try {
      const json j = json::parse(g.toStdString());
      auto t = std::make_shared<app::GroundTruth>();
      t->pose = poseFrom(j.at("pose"));
      const auto& a = j.at("appearance");
      t->appearance.lightPosition = vec3(a.at("light_position"));
      t->appearance.kd = vec3(a.at("kd"));
      t->appearance.ks = vec3(a.at("ks"));
      t->appearance.roughness = a.at("roughness").get<double>();
      t->appearance.falloff = a.value("falloff", 0.0);
      for (const auto& s : j.at("vessel_tree")) {
        t->vesselAxes.emplace_back(vec3(s.at("a")), vec3(s.at("b")));
        t->vesselRadii.push_back(s.at("radius").get<double>());
      }
      c.groundTruth = t;
    } catch (const std::exception& e) {
      note(QStringLiteral("Ground truth not loaded: %1").arg(QString::fromUtf8(e.what())));
    }
  }
  return c;
}

}  // namespace rehearse::ui
