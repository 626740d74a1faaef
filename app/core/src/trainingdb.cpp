#include "rehearse/app/trainingdb.hpp"

#include <libpq-fe.h>
#include <openssl/evp.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <charconv>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <system_error>
#include <thread>

namespace rehearse::app {

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

// The operating system's name as users know it (os-release's PRETTY_NAME, as Qt's QSysInfo::prettyProductName read
// it); else the kernel's name and release.
std::string prettyOsName() {
  for (const char* path : {"/etc/os-release", "/usr/lib/os-release"}) {
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("PRETTY_NAME=", 0) != 0) continue;
      std::string v = line.substr(12);
      if (v.size() >= 2 && (v.front() == '"' || v.front() == '\'') && v.back() == v.front())
        v = v.substr(1, v.size() - 2);
      if (!v.empty()) return v;
    }
  }
  struct utsname u {};
  if (uname(&u) != 0) return "unknown";
  std::string kernel = u.sysname;
  for (char& c : kernel) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return kernel + " " + u.release;
}

// The processor's architecture in QSysInfo::currentCpuArchitecture's words (x86_64, i386, arm64, ...).
std::string cpuArchitecture() {
  struct utsname u {};
  if (uname(&u) != 0) return "unknown";
  const std::string m = u.machine;
  if (m == "amd64") return "x86_64";
  if (m.size() == 4 && m[0] == 'i' && m[2] == '8' && m[3] == '6') return "i386";
  if (m == "aarch64") return "arm64";
  if (m.rfind("armv", 0) == 0) return "arm";
  return m;
}

std::string hostName() {
  std::array<char, 256> name{};
  if (gethostname(name.data(), name.size() - 1) != 0) return {};
  return name.data();
}

// This machine and build, as a verification names them.
std::string thisMachine() {
  return hostName() + " (" + cpuArchitecture() + ", " + prettyOsName() + ", Rehearse " REHEARSE_VERSION ")";
}

// The server's or libpq's message on one line (its DETAIL and HINT lines joined, no trailing newline).
std::string oneLine(const char* text) {
  std::string out;
  bool space = false;
  for (const char* p = text ? text : ""; *p; ++p) {
    if (std::isspace(static_cast<unsigned char>(*p))) {
      space = !out.empty();
      continue;
    }
    if (space) out += ' ';
    space = false;
    out += *p;
  }
  return out;
}

std::runtime_error dbError(const std::string& what, const char* message) {
  return std::runtime_error(what + ": " + oneLine(message));
}

struct ResultFree {
  void operator()(PGresult* r) const { PQclear(r); }
};
using Result = std::unique_ptr<PGresult, ResultFree>;

// One parameter of a statement: text, or bytes (BYTEA, sent in binary).
struct Param {
  std::string value;
  bool binary = false;
};
Param text(std::string s) {
  return {std::move(s), false};
}
Param bytes(std::string s) {
  return {std::move(s), true};
}
Param number(long long v) {
  return {std::to_string(v), false};
}
Param number(double v) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);  // shortest exact form, whatever the locale
  return {std::string(buf.data(), r.ptr), false};
}

// A column of a row of a text result ("" for NULL, as Qt SQL's toString gave).
std::string value(const PGresult* r, int row, int column) {
  return std::string(PQgetvalue(r, row, column), static_cast<std::size_t>(PQgetlength(r, row, column)));
}
// A number column; 0 for NULL or anything else than a number (as QVariant's toLongLong gave).
template <class T>
T numberAt(const PGresult* r, int row, int column) {
  const std::string s = value(r, row, column);
  T v{};
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() ? v : T{};
}
bool boolAt(const PGresult* r, int row, int column) {
  return value(r, row, column) == "t";
}

}  // namespace

struct TrainingDatabase::Impl {
  PGconn* conn = nullptr;
  std::thread::id owner = std::this_thread::get_id();
  ~Impl() {
    if (conn) PQfinish(conn);
  }

  // Runs one statement, its values as parameters (never spliced into the SQL); `binaryResult`: its columns as bytes
  // (a BYTEA). The connection is the thread's that opened it, as Qt SQL's was: from another it throws.
  Result exec(const char* sql, const std::vector<Param>& params, const std::string& what, bool binaryResult = false) {
    if (std::this_thread::get_id() != owner)
      throw std::runtime_error(what + ": its connection belongs to the thread that opened it");
    std::vector<const char*> values;
    std::vector<int> lengths, formats;
    for (const Param& p : params) {
      values.push_back(p.value.c_str());
      lengths.push_back(static_cast<int>(p.value.size()));
      formats.push_back(p.binary ? 1 : 0);
    }
    Result r(PQexecParams(conn, sql, static_cast<int>(params.size()), nullptr, values.data(), lengths.data(),
                          formats.data(), binaryResult ? 1 : 0));
    const ExecStatusType status = r ? PQresultStatus(r.get()) : PGRES_FATAL_ERROR;
    if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK)
      throw dbError(what, r ? PQresultErrorMessage(r.get()) : PQerrorMessage(conn));
    return r;
  }
  void exec(const char* sql, const std::string& what) { exec(sql, {}, what); }
  // COMMIT: a transaction the server aborted answers ROLLBACK, which is no commit (as Qt SQL's driver checked).
  bool commit(std::string* why = nullptr) {
    Result r(PQexec(conn, "COMMIT"));
    const bool ok =
        r && PQresultStatus(r.get()) == PGRES_COMMAND_OK && std::strcmp(PQcmdStatus(r.get()), "ROLLBACK") != 0;
    if (!ok && why) {
      *why = oneLine(r ? PQresultErrorMessage(r.get()) : PQerrorMessage(conn));
      if (why->empty()) *why = "the transaction was rolled back";
    }
    return ok;
  }
  void rollback() { Result r(PQexec(conn, "ROLLBACK")); }
};

std::string sessionUid(const RecordingRows& rows, const RecordingSummary& s) {
  // Each field as its size (8 bytes, native order, as QCryptographicHash was given a qint64) then its bytes: the
  // identity of sessions already published.
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> h(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
  if (!h || EVP_DigestInit_ex(h.get(), EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("SHA-256 is not available (OpenSSL)");
  auto add = [&h](const std::string& text) {
    const std::int64_t n = static_cast<std::int64_t>(text.size());
    if (EVP_DigestUpdate(h.get(), &n, sizeof n) != 1 || EVP_DigestUpdate(h.get(), text.data(), text.size()) != 1)
      throw std::runtime_error("SHA-256 failed (OpenSSL)");
  };
  for (const auto& t : {s.meta.trainee, s.meta.caseName, s.meta.sceneVersion, s.meta.appVersion, s.meta.notes,
                        s.startedUtc, rows.setup})
    add(t);
  if (!s.meta.rules.empty()) add("rules:" + s.meta.rules);  // (a session without its own rules keeps its old uid)
  for (const auto& e : rows.events)
    add(std::to_string(std::get<0>(e)) + ":" + std::to_string(std::get<1>(e)) + ":" + std::get<2>(e));
  for (const auto& [step, sum] : rows.checksums) add(std::to_string(step) + ":" + sum);
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_DigestFinal_ex(h.get(), md, &length) != 1) throw std::runtime_error("SHA-256 failed (OpenSSL)");
  static const char* const hex = "0123456789abcdef";
  std::string out;
  for (unsigned int k = 0; k < length; ++k) {
    out += hex[md[k] >> 4];
    out += hex[md[k] & 15];
  }
  return out;
}

TrainingDatabase::TrainingDatabase(const std::string& service) : d_(std::make_shared<Impl>()) {
  // Everything else (host, port, database, user, password file, TLS) from the service file or the environment; the
  // service's name is passed as a value, never spliced into a connection string.
  const char* keywords[] = {"service", nullptr};
  const char* values[] = {service.c_str(), nullptr};
  d_->conn = service.empty() ? PQconnectdb("") : PQconnectdbParams(keywords, values, 0);
  if (!d_->conn) throw std::runtime_error("cannot connect to the training database: out of memory");
  if (PQstatus(d_->conn) != CONNECTION_OK)
    throw dbError("cannot connect to the training database", PQerrorMessage(d_->conn));
  // The server's notices are not printed on stderr (libpq's default): Qt SQL's driver kept them to its debug log.
  PQsetNoticeProcessor(
      d_->conn, [](void*, const char*) {}, nullptr);
  if (PQsetClientEncoding(d_->conn, "UTF8") != 0)  // std::string holds UTF-8, whatever PGCLIENTENCODING says
    throw dbError("the training database refused a setting", PQerrorMessage(d_->conn));
  d_->exec("SET client_min_messages TO WARNING", "the training database refused a setting");  // no NOTICEs
  // Two publishers starting at once must not race to create the tables.
  d_->exec("SELECT pg_advisory_lock(16160001)", "the training database refused a lock");
  try {
    for (const char* sql : kSchema) d_->exec(sql, "the training database's tables cannot be created");
  } catch (...) {
    d_->exec("SELECT pg_advisory_unlock(16160001)", "unlock");
    throw;
  }
  d_->exec("SELECT pg_advisory_unlock(16160001)", "the training database refused an unlock");
}

TrainingDatabase::~TrainingDatabase() = default;

TrainingDatabase::PublishReport TrainingDatabase::publish(const std::string& file,
                                                          const std::function<bool(int, int)>& progress) {
  PublishReport r;
  const auto list = listRecordings(file);
  Impl& db = *d_;
  int done = 0;
  for (const auto& s : list) {
    if (progress && !progress(done, static_cast<int>(list.size()))) break;
    ++done;
    if (!s.complete) {
      ++r.skipped;
      r.notes.push_back(file + ": session " + std::to_string(s.id) +
                        " is not complete (being recorded, or cut short): not published");
      continue;
    }
    const RecordingRows rows = loadRecordingRows(file, s.id);
    const std::string uid = sessionUid(rows, s);
    if (PQntuples(db.exec("SELECT 1 FROM rehearse_sessions WHERE uid = $1", {text(uid)},
                          "the training database cannot be read")
                      .get()) > 0) {
      ++r.already;
      continue;
    }
    // Replayed before it is published: a session that does not reproduce its recording is refused.
    const Recording rec = loadRecording(file, s.id);
    ReplayOptions options;
    options.strain = true;
    const ReplayResult replayed = replayRecording(rec, options);
    if (replayed.verify.checked == 0 || replayed.verify.mismatches > 0) {
      ++r.skipped;
      r.notes.push_back(file + ": session " + std::to_string(s.id) + " was refused: " +
                        (replayed.verify.checked == 0
                             ? std::string("it has no checksum to verify its replay against")
                             : std::to_string(replayed.verify.mismatches) + " of " +
                                   std::to_string(replayed.verify.checked) + " checksums differ on replay"));
      continue;
    }
    nlohmann::json metrics;
    for (const auto& m : metricValues(replayed.metrics))
      metrics[m.name] = m.value ? nlohmann::json(*m.value) : nlohmann::json(nullptr);
    db.exec("BEGIN", "the training database refused a transaction");
    try {
      db.exec("SELECT pg_advisory_xact_lock(hashtextextended($1, 0))", {text(uid)},
              "the training database refused a lock");
      if (PQntuples(db.exec("SELECT 1 FROM rehearse_sessions WHERE uid = $1", {text(uid)},
                            "the training database cannot be read")
                        .get()) > 0) {
        db.commit();  // another publisher wrote it meanwhile
        ++r.already;
        continue;
      }
      db.exec(
          "INSERT INTO rehearse_sessions(uid, trainee, started_utc, case_name, scene_version, app_version, notes, "
          "setup, "
          "time_step, checksum_every, steps, complete, metrics, verified_on, rules) VALUES($1, $2, $3, $4, $5, $6, $7, "
          "$8, $9, $10, $11, $12, $13, $14, $15)",
          {text(uid), text(s.meta.trainee), text(s.startedUtc), text(s.meta.caseName), text(s.meta.sceneVersion),
           text(s.meta.appVersion), text(s.meta.notes), text(rows.setup), number(rec.setup.settings.timeStep),
           number(static_cast<long long>(rec.checksumEvery)), number(static_cast<long long>(s.steps)), text("true"),
           text(metrics.dump()),
           text("all " + std::to_string(replayed.verify.checked) + " checksums match on " + thisMachine()),
           text(s.meta.rules)},
          "the training database refused a session");
      for (const auto& [seq, step, event] : rows.events)
        db.exec("INSERT INTO rehearse_events(uid, seq, step, event) VALUES($1, $2, $3, $4)",
                {text(uid), number(static_cast<long long>(seq)), number(static_cast<long long>(step)), text(event)},
                "the training database refused an event");
      for (const auto& [step, sum] : rows.checksums)
        db.exec("INSERT INTO rehearse_checksums(uid, step, checksum) VALUES($1, $2, $3)",
                {text(uid), number(static_cast<long long>(step)), text(sum)},
                "the training database refused a checksum");
      for (const auto& [hash, setup] : rows.setups)
        db.exec("INSERT INTO rehearse_setups(uid, hash, setup) VALUES($1, $2, $3)",
                {text(uid), text(hash), text(setup)}, "the training database refused a setup");
      for (const auto& cp : rows.checkpoints)
        db.exec("INSERT INTO rehearse_checkpoints(uid, step, setup_hash, state) VALUES($1, $2, $3, $4)",
                {text(uid), number(static_cast<long long>(cp.step)), text(cp.setupHash), bytes(cp.state)},
                "the training database refused a checkpoint");
      if (std::string why; !db.commit(&why))
        throw std::runtime_error("the training database did not commit a session: " + why);
      ++r.published;
    } catch (...) {
      db.rollback();
      throw;
    }
  }
  return r;
}

std::vector<PublishedSession> TrainingDatabase::sessions() {
  const Result q = d_->exec(
      R"(SELECT id, uid, trainee, started_utc, case_name, scene_version, app_version, notes, steps, complete, )"
      R"(to_char(published_utc AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS"Z"'), metrics, verified_on )"
      R"(FROM rehearse_sessions ORDER BY started_utc, id)",
      {}, "the training database cannot be read");
  std::vector<PublishedSession> out;
  for (int row = 0; row < PQntuples(q.get()); ++row) {
    const PGresult* r = q.get();
    PublishedSession p;
    p.id = numberAt<std::int64_t>(r, row, 0);
    p.uid = value(r, row, 1);
    p.summary.id = p.id;
    p.summary.meta = {value(r, row, 2), value(r, row, 4), value(r, row, 5), value(r, row, 6), value(r, row, 7), ""};
    p.summary.startedUtc = value(r, row, 3);
    p.summary.steps = static_cast<long>(numberAt<std::int64_t>(r, row, 8));
    p.summary.complete = boolAt(r, row, 9);
    p.publishedUtc = value(r, row, 10);
    p.verifiedOn = value(r, row, 12);
    try {
      const auto j = nlohmann::json::parse(value(r, row, 11));
      for (const auto& m : metricValues(SessionMetrics{})) {
        MetricValue v = m;
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

Recording TrainingDatabase::load(std::int64_t id) {
  Impl& db = *d_;
  Recording r;
  std::string uid;
  {
    const Result q = db.exec(
        "SELECT uid, trainee, started_utc, case_name, scene_version, app_version, notes, setup, checksum_every, steps, "
        "complete, rules FROM rehearse_sessions WHERE id = $1",
        {number(static_cast<long long>(id))}, "the training database cannot be read");
    if (PQntuples(q.get()) == 0) throw std::runtime_error("the training database has no session " + std::to_string(id));
    const PGresult* s = q.get();
    uid = value(s, 0, 0);
    r.summary.id = id;
    r.summary.meta = {value(s, 0, 1), value(s, 0, 3), value(s, 0, 4), value(s, 0, 5), value(s, 0, 6), ""};
    r.summary.startedUtc = value(s, 0, 2);
    r.setup = decodeSetup(value(s, 0, 7), &r.numerics);
    r.checksumEvery = numberAt<int>(s, 0, 8);
    r.summary.steps = static_cast<long>(numberAt<std::int64_t>(s, 0, 9));
    r.summary.complete = boolAt(s, 0, 10);
    r.summary.meta.rules = value(s, 0, 11);
  }
  {
    const Result e = db.exec("SELECT event FROM rehearse_events WHERE uid = $1 ORDER BY seq", {text(uid)},
                             "the training database cannot be read");
    for (int row = 0; row < PQntuples(e.get()); ++row) r.events.push_back(decodeEvent(value(e.get(), row, 0)));
  }
  {
    const Result c = db.exec("SELECT step, checksum FROM rehearse_checksums WHERE uid = $1 ORDER BY step", {text(uid)},
                             "the training database cannot be read");
    for (int row = 0; row < PQntuples(c.get()); ++row)
      r.checksums[static_cast<long>(numberAt<std::int64_t>(c.get(), row, 0))] =
          numberAt<std::uint64_t>(c.get(), row, 1);
  }
  {
    const Result k = db.exec("SELECT step FROM rehearse_checkpoints WHERE uid = $1 ORDER BY step", {text(uid)},
                             "the training database cannot be read");
    for (int row = 0; row < PQntuples(k.get()); ++row)
      r.checkpointSteps.push_back(static_cast<long>(numberAt<std::int64_t>(k.get(), row, 0)));
  }
  r.path = "postgresql session " + uid;
  // Checkpoints are read as seeking needs them (the connection is this object's: the same thread).
  r.checkpointSource = [d = d_, uid](long step) {
    const Result q = d->exec("SELECT state FROM rehearse_checkpoints WHERE uid = $1 AND step = $2",
                             {text(uid), number(static_cast<long long>(step))}, "the training database cannot be read",
                             true);  // the BYTEA's bytes as they are
    if (PQntuples(q.get()) == 0)
      throw std::runtime_error("the training database has no checkpoint at step " + std::to_string(step));
    return decodeCheckpointState(value(q.get(), 0, 0), [&](std::uint64_t hash) {
      const Result s = d->exec("SELECT setup FROM rehearse_setups WHERE uid = $1 AND hash = $2",
                               {text(uid), text(std::to_string(hash))}, "the training database cannot be read");
      if (PQntuples(s.get()) == 0) throw std::runtime_error("a published checkpoint names a setup that is missing");
      return decodeSharedSetup(value(s.get(), 0, 0), hash);
    });
  };
  if (const std::string why = recordingLengthProblem(r); !why.empty())
    throw std::runtime_error("the published session " + std::to_string(id) + " " + why);
  return r;
}

}  // namespace rehearse::app
