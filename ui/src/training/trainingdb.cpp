#include "rehearse/ui/trainingdb.hpp"

#include <rehearse/app/review.hpp>

#include <nlohmann/json.hpp>

#include <QCryptographicHash>
#include <QSqlDatabase>
#include <QSqlError>
#include <QSqlQuery>
#include <QSysInfo>
#include <QVariant>

#include <atomic>
#include <stdexcept>

namespace rehearse::ui {

namespace {

constexpr const char* kSchema[] = {
    "CREATE TABLE IF NOT EXISTS rehearse_sessions(id BIGSERIAL UNIQUE, uid TEXT PRIMARY KEY, trainee TEXT, started_utc "
    "TEXT, case_name TEXT, "
    "scene_version TEXT, app_version TEXT, notes TEXT, setup TEXT NOT NULL, time_step DOUBLE PRECISION, checksum_every "
    "INTEGER, steps BIGINT, "
    "complete BOOLEAN, published_utc TIMESTAMPTZ DEFAULT now(), metrics TEXT)",
    "CREATE TABLE IF NOT EXISTS rehearse_events(uid TEXT NOT NULL REFERENCES rehearse_sessions(uid) ON DELETE CASCADE, "
    "seq INTEGER NOT NULL, "
    "step BIGINT NOT NULL, event TEXT NOT NULL, PRIMARY KEY(uid, seq))",
    "CREATE TABLE IF NOT EXISTS rehearse_checksums(uid TEXT NOT NULL REFERENCES rehearse_sessions(uid) ON DELETE "
    "CASCADE, step BIGINT NOT NULL, "
    "checksum TEXT NOT NULL, PRIMARY KEY(uid, step))",
    "CREATE TABLE IF NOT EXISTS rehearse_setups(uid TEXT NOT NULL REFERENCES rehearse_sessions(uid) ON DELETE CASCADE, "
    "hash TEXT NOT NULL, "
    "setup TEXT NOT NULL, PRIMARY KEY(uid, hash))",
    "CREATE TABLE IF NOT EXISTS rehearse_checkpoints(uid TEXT NOT NULL REFERENCES rehearse_sessions(uid) ON DELETE "
    "CASCADE, step BIGINT NOT NULL, "
    "setup_hash TEXT NOT NULL, state BYTEA NOT NULL, PRIMARY KEY(uid, step))",
    // Where its replay was verified before it was published (a replay is bit-exact with the same build on any x86-64
    // processor, its kernels pinned): a receiving machine verifies again when it opens the session and says where.
    "ALTER TABLE rehearse_sessions ADD COLUMN IF NOT EXISTS verified_on TEXT",
    // The incorrect-action rules of the scene it was rehearsed in (SessionMeta::rules).
    "ALTER TABLE rehearse_sessions ADD COLUMN IF NOT EXISTS rules TEXT",
};

// This machine and build, as a verification names them.
QString thisMachine() {
  return QStringLiteral("%1 (%2, %3, Rehearse %4)")
      .arg(QSysInfo::machineHostName(), QSysInfo::currentCpuArchitecture(), QSysInfo::prettyProductName(), QStringLiteral(REHEARSE_VERSION));
}

std::runtime_error dbError(const std::string& what, const QSqlError& e) {
  QString text = e.text().simplified();
  return std::runtime_error(what + ": " + text.toStdString());
}

void run(QSqlQuery& q, const std::string& what) {
  if (!q.exec()) throw dbError(what, q.lastError());
}

void run(const QSqlDatabase& db, const QString& sql, const std::string& what) {
  QSqlQuery q(db);
  if (!q.exec(sql)) throw dbError(what, q.lastError());
}

}  // namespace

struct TrainingDatabase::Impl {
  QString name;
  QSqlDatabase db() const { return QSqlDatabase::database(name, false); }
  ~Impl() {
    {
      QSqlDatabase d = QSqlDatabase::database(name, false);
      if (d.isValid()) d.close();
    }
    QSqlDatabase::removeDatabase(name);
  }
};

QString sessionUid(const app::RecordingRows& rows, const app::RecordingSummary& s) {
  QCryptographicHash h(QCryptographicHash::Sha256);
  auto add = [&h](const std::string& text) {
    const QByteArray b = QByteArray::fromStdString(text);
    const qint64 n = b.size();
    h.addData(QByteArrayView(reinterpret_cast<const char*>(&n), sizeof n));
    h.addData(b);
  };
  for (const auto& t : {s.meta.trainee, s.meta.caseName, s.meta.sceneVersion, s.meta.appVersion, s.meta.notes, s.startedUtc, rows.setup}) add(t);
  if (!s.meta.rules.empty()) add("rules:" + s.meta.rules);  // (a session without its own rules keeps its old uid)
  for (const auto& e : rows.events) add(std::to_string(std::get<0>(e)) + ":" + std::to_string(std::get<1>(e)) + ":" + std::get<2>(e));
  for (const auto& [step, sum] : rows.checksums) add(std::to_string(step) + ":" + sum);
  return QString::fromLatin1(h.result().toHex());
}

TrainingDatabase::TrainingDatabase(const QString& service) : d_(std::make_shared<Impl>()) {
  if (!QSqlDatabase::isDriverAvailable(QStringLiteral("QPSQL")))
    throw std::runtime_error("Qt SQL's PostgreSQL driver is not installed (Debian: libqt6sql6-psql)");
  static std::atomic<int> counter{0};
  d_->name = QStringLiteral("rehearse-training-%1").arg(++counter);
  QSqlDatabase db = QSqlDatabase::addDatabase(QStringLiteral("QPSQL"), d_->name);
  // Everything else (host, port, database, user, password file, TLS) from the service file or the environment.
  if (!service.isEmpty()) db.setConnectOptions(QStringLiteral("service=") + service);
  if (!db.open()) throw dbError("cannot connect to the training database", db.lastError());
  run(db, QStringLiteral("SET client_min_messages TO WARNING"), "the training database refused a setting");  // no NOTICEs on stderr
  // Two publishers starting at once must not race to create the tables.
  run(db, QStringLiteral("SELECT pg_advisory_lock(16160001)"), "the training database refused a lock");
  try {
    for (const char* sql : kSchema) run(db, QString::fromLatin1(sql), "the training database's tables cannot be created");
  } catch (...) {
    run(db, QStringLiteral("SELECT pg_advisory_unlock(16160001)"), "unlock");
    throw;
  }
  run(db, QStringLiteral("SELECT pg_advisory_unlock(16160001)"), "the training database refused an unlock");
}

TrainingDatabase::~TrainingDatabase() = default;

TrainingDatabase::PublishReport TrainingDatabase::publish(const QString& caseFile, const std::function<bool(int, int)>& progress) {
  PublishReport r;
  const std::string file = caseFile.toStdString();
  const auto list = app::listRecordings(file);
  QSqlDatabase db = d_->db();
  int done = 0;
  for (const auto& s : list) {
    if (progress && !progress(done, static_cast<int>(list.size()))) break;
    ++done;
    if (!s.complete) {
      ++r.skipped;
      r.notes << QStringLiteral("%1: session %2 is not complete (being recorded, or cut short): not published").arg(caseFile).arg(s.id);
      continue;
    }
    const app::RecordingRows rows = app::loadRecordingRows(file, s.id);
    const QString uid = sessionUid(rows, s);
    {
      QSqlQuery q(db);
      q.prepare(QStringLiteral("SELECT 1 FROM rehearse_sessions WHERE uid = ?"));
      q.addBindValue(uid);
      run(q, "the training database cannot be read");
      if (q.next()) {
        ++r.already;
        continue;
      }
    }
    // Replayed before it is published: a session that does not reproduce its recording is refused.
    const app::Recording rec = app::loadRecording(file, s.id);
    app::ReplayOptions options;
    options.strain = true;
    const app::ReplayResult replayed = app::replayRecording(rec, options);
    if (replayed.verify.checked == 0 || replayed.verify.mismatches > 0) {
      ++r.skipped;
      r.notes << QStringLiteral("%1: session %2 was refused: %3").arg(caseFile).arg(s.id)
                     .arg(replayed.verify.checked == 0 ? QStringLiteral("it has no checksum to verify its replay against")
                                                       : QStringLiteral("%1 of %2 checksums differ on replay").arg(replayed.verify.mismatches).arg(replayed.verify.checked));
      continue;
    }
    nlohmann::json metrics;
    for (const auto& m : app::metricValues(replayed.metrics)) metrics[m.name] = m.value ? nlohmann::json(*m.value) : nlohmann::json(nullptr);
    if (!db.transaction()) throw dbError("the training database refused a transaction", db.lastError());
    try {
      {
        QSqlQuery q(db);
        q.prepare(QStringLiteral("SELECT pg_advisory_xact_lock(hashtextextended(?, 0))"));
        q.addBindValue(uid);
        run(q, "the training database refused a lock");
        q.prepare(QStringLiteral("SELECT 1 FROM rehearse_sessions WHERE uid = ?"));
        q.addBindValue(uid);
        run(q, "the training database cannot be read");
        if (q.next()) {  // another publisher wrote it meanwhile
          db.commit();
          ++r.already;
          continue;
        }
      }
      QSqlQuery q(db);
      q.prepare(
          QStringLiteral("INSERT INTO rehearse_sessions(uid, trainee, started_utc, case_name, scene_version, "
                         "app_version, notes, setup, time_step, "
                         "checksum_every, steps, complete, metrics, verified_on, rules) VALUES(?, ?, ?, ?, ?, ?, ?, ?, "
                         "?, ?, ?, ?, ?, ?, ?)"));
      for (const QVariant& v :
           {QVariant(uid), QVariant(QString::fromStdString(s.meta.trainee)),
            QVariant(QString::fromStdString(s.startedUtc)), QVariant(QString::fromStdString(s.meta.caseName)),
            QVariant(QString::fromStdString(s.meta.sceneVersion)), QVariant(QString::fromStdString(s.meta.appVersion)),
            QVariant(QString::fromStdString(s.meta.notes)), QVariant(QString::fromStdString(rows.setup)),
            QVariant(rec.setup.settings.timeStep), QVariant(rec.checksumEvery),
            QVariant(static_cast<qlonglong>(s.steps)), QVariant(true), QVariant(QString::fromStdString(metrics.dump())),
            QVariant(QStringLiteral("all %1 checksums match on %2").arg(replayed.verify.checked).arg(thisMachine())),
            QVariant(QString::fromStdString(s.meta.rules))})
        q.addBindValue(v);
      run(q, "the training database refused a session");
      QSqlQuery e(db);
      e.prepare(QStringLiteral("INSERT INTO rehearse_events(uid, seq, step, event) VALUES(?, ?, ?, ?)"));
      for (const auto& [seq, step, text] : rows.events) {
        e.bindValue(0, uid);
        e.bindValue(1, static_cast<qlonglong>(seq));
        e.bindValue(2, static_cast<qlonglong>(step));
        e.bindValue(3, QString::fromStdString(text));
        run(e, "the training database refused an event");
      }
      QSqlQuery c(db);
      c.prepare(QStringLiteral("INSERT INTO rehearse_checksums(uid, step, checksum) VALUES(?, ?, ?)"));
      for (const auto& [step, sum] : rows.checksums) {
        c.bindValue(0, uid);
        c.bindValue(1, static_cast<qlonglong>(step));
        c.bindValue(2, QString::fromStdString(sum));
        run(c, "the training database refused a checksum");
      }
      QSqlQuery st(db);
      st.prepare(QStringLiteral("INSERT INTO rehearse_setups(uid, hash, setup) VALUES(?, ?, ?)"));
      for (const auto& [hash, text] : rows.setups) {
        st.bindValue(0, uid);
        st.bindValue(1, QString::fromStdString(hash));
        st.bindValue(2, QString::fromStdString(text));
        run(st, "the training database refused a setup");
      }
      QSqlQuery k(db);
      k.prepare(QStringLiteral("INSERT INTO rehearse_checkpoints(uid, step, setup_hash, state) VALUES(?, ?, ?, ?)"));
      for (const auto& cp : rows.checkpoints) {
        k.bindValue(0, uid);
        k.bindValue(1, static_cast<qlonglong>(cp.step));
        k.bindValue(2, QString::fromStdString(cp.setupHash));
        k.bindValue(3, QByteArray::fromStdString(cp.state));
        run(k, "the training database refused a checkpoint");
      }
      if (!db.commit()) throw dbError("the training database did not commit a session", db.lastError());
      ++r.published;
    } catch (...) {
      db.rollback();
      throw;
    }
  }
  return r;
}

std::vector<PublishedSession> TrainingDatabase::sessions() {
  QSqlQuery q(d_->db());
  q.prepare(QStringLiteral("SELECT id, uid, trainee, started_utc, case_name, scene_version, app_version, notes, steps, complete, "
                           "to_char(published_utc AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'), metrics, verified_on FROM rehearse_sessions ORDER BY started_utc, id"));
  run(q, "the training database cannot be read");
  std::vector<PublishedSession> out;
  while (q.next()) {
    PublishedSession p;
    p.id = q.value(0).toLongLong();
    p.uid = q.value(1).toString();
    p.summary.id = p.id;
    p.summary.meta = {q.value(2).toString().toStdString(), q.value(4).toString().toStdString(),
                      q.value(5).toString().toStdString(), q.value(6).toString().toStdString(),
                      q.value(7).toString().toStdString(), ""};
    p.summary.startedUtc = q.value(3).toString().toStdString();
    p.summary.steps = static_cast<long>(q.value(8).toLongLong());
    p.summary.complete = q.value(9).toBool();
    p.publishedUtc = q.value(10).toString();
    p.verifiedOn = q.value(12).toString();
    try {
      const auto j = nlohmann::json::parse(q.value(11).toString().toStdString());
      for (const auto& m : app::metricValues(app::SessionMetrics{})) {
        app::MetricValue v = m;
        v.value.reset();
        if (j.contains(m.name) && j[m.name].is_number()) v.value = j[m.name].get<double>();
        p.metrics.push_back(v);
      }
    } catch (const std::exception&) {
    }
    out.push_back(std::move(p));
  }
  return out;
}

app::Recording TrainingDatabase::load(qint64 id) {
  QSqlDatabase db = d_->db();
  app::Recording r;
  QString uid;
  {
    QSqlQuery q(db);
    q.prepare(
        QStringLiteral("SELECT uid, trainee, started_utc, case_name, scene_version, app_version, notes, setup, "
                       "checksum_every, steps, complete, "
                       "rules FROM rehearse_sessions WHERE id = ?"));
    q.addBindValue(id);
    run(q, "the training database cannot be read");
    if (!q.next()) throw std::runtime_error("the training database has no session " + std::to_string(id));
    uid = q.value(0).toString();
    r.summary.id = id;
    r.summary.meta = {q.value(1).toString().toStdString(), q.value(3).toString().toStdString(),
                      q.value(4).toString().toStdString(), q.value(5).toString().toStdString(),
                      q.value(6).toString().toStdString(), ""};
    r.summary.startedUtc = q.value(2).toString().toStdString();
    r.setup = app::decodeSetup(q.value(7).toString().toStdString(), &r.numerics);
    r.checksumEvery = q.value(8).toInt();
    r.summary.steps = static_cast<long>(q.value(9).toLongLong());
    r.summary.complete = q.value(10).toBool();
    r.summary.meta.rules = q.value(11).toString().toStdString();
  }
  QSqlQuery e(db);
  e.prepare(QStringLiteral("SELECT event FROM rehearse_events WHERE uid = ? ORDER BY seq"));
  e.addBindValue(uid);
  run(e, "the training database cannot be read");
  while (e.next()) r.events.push_back(app::decodeEvent(e.value(0).toString().toStdString()));
  QSqlQuery c(db);
  c.prepare(QStringLiteral("SELECT step, checksum FROM rehearse_checksums WHERE uid = ? ORDER BY step"));
  c.addBindValue(uid);
  run(c, "the training database cannot be read");
  while (c.next()) r.checksums[static_cast<long>(c.value(0).toLongLong())] = c.value(1).toString().toULongLong();
  QSqlQuery k(db);
  k.prepare(QStringLiteral("SELECT step FROM rehearse_checkpoints WHERE uid = ? ORDER BY step"));
  k.addBindValue(uid);
  run(k, "the training database cannot be read");
  while (k.next()) r.checkpointSteps.push_back(static_cast<long>(k.value(0).toLongLong()));
  r.path = "postgresql session " + uid.toStdString();
  // Checkpoints are read as seeking needs them (the connection is this object's: the same thread).
  r.checkpointSource = [d = d_, uid](long step) {
    QSqlDatabase db = d->db();
    QSqlQuery q(db);
    q.prepare(QStringLiteral("SELECT state FROM rehearse_checkpoints WHERE uid = ? AND step = ?"));
    q.addBindValue(uid);
    q.addBindValue(static_cast<qlonglong>(step));
    run(q, "the training database cannot be read");
    if (!q.next()) throw std::runtime_error("the training database has no checkpoint at step " + std::to_string(step));
    const QByteArray bytes = q.value(0).toByteArray();
    return app::decodeCheckpointState(bytes.toStdString(), [&](std::uint64_t hash) {
      QSqlQuery s(db);
      s.prepare(QStringLiteral("SELECT setup FROM rehearse_setups WHERE uid = ? AND hash = ?"));
      s.addBindValue(uid);
      s.addBindValue(QString::number(hash));
      run(s, "the training database cannot be read");
      if (!s.next()) throw std::runtime_error("a published checkpoint names a setup that is missing");
      return app::decodeSharedSetup(s.value(0).toString().toStdString(), hash);
    });
  };
  if (const std::string why = app::recordingLengthProblem(r); !why.empty())
    throw std::runtime_error("the published session " + std::to_string(id) + " " + why);
  return r;
}

}  // namespace rehearse::ui
