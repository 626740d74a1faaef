#pragma once
// The training centre's database (issue 16): recorded sessions published from case files into PostgreSQL
// (libpq's C API, no Qt: the command line reaches it in every build), read back by the review window, the cohort
// view and `rehearse replay postgresql:[SERVICE]`. The connection comes from a libpq service name (pg_service.conf,
// PGSERVICEFILE) or the environment (PGHOST, PGPORT, PGDATABASE, PGUSER, PGPASSFILE, PGSSLMODE); no credential is
// ever written into a case file or a log.
//
// Publishing is idempotent and resumable: a session is identified by the SHA-256 of its content (meta, setup,
// events, checksums), written in one transaction (a killed publisher leaves nothing of the session it was
// writing), under a transaction-scoped advisory lock on that identity (two publishers at once: one writes it,
// the other finds it there). Each session is replayed before it is published: one whose replay differs from
// its recording is refused, and the metrics of the replay are stored with it (the cohort view's numbers).
//
// A connection belongs to the thread that opened it (as Qt SQL's did): used from another thread (a checkpoint read
// by a worker's seek, say) it throws, and the caller goes on without it (ReplayOptions::checkpoints says so).
#include <cstdint>
#include <functional>
#include <memory>
#include <rehearse/app/recording.hpp>
#include <rehearse/app/review.hpp>
#include <string>
#include <vector>

namespace rehearse::app {

/// The content identity of a recorded session (hex SHA-256).
std::string sessionUid(const RecordingRows& rows, const RecordingSummary& summary);

struct PublishedSession {
  std::int64_t id = 0;  ///< the database's number for it
  std::string uid;
  RecordingSummary summary;
  std::string publishedUtc;
  std::string verifiedOn;  ///< where its replay was verified before publishing ("all 35 checksums match on HOST
                           ///< (...)"); empty: published before this was kept
  std::vector<MetricValue> metrics;  ///< as computed at publishing (force threshold 10 N)
};

class TrainingDatabase {
 public:
  /// Connects and creates the tables when absent. `service`: a libpq service name; empty: the environment.
  /// Throws std::runtime_error with one sentence (no server, refused).
  explicit TrainingDatabase(const std::string& service = {});
  ~TrainingDatabase();
  TrainingDatabase(const TrainingDatabase&) = delete;
  TrainingDatabase& operator=(const TrainingDatabase&) = delete;

  struct PublishReport {
    int published = 0;  ///< written now
    int already = 0;    ///< found there (published before, or by another publisher at the same time)
    int skipped = 0;    ///< not complete (being recorded, or cut short) or refused (notes say why)
    std::vector<std::string> notes;
  };
  /// Publishes every complete session of a case file. `progress(done, total)` returning false stops between
  /// sessions (what was published stays). Throws std::runtime_error with one sentence on a database error.
  PublishReport publish(const std::string& caseFile, const std::function<bool(int, int)>& progress = {});
  std::vector<PublishedSession> sessions();
  /// A published session as a recording (its checkpoints read from the database as seeking needs them).
  Recording load(std::int64_t id);

 private:
  struct Impl;
  std::shared_ptr<Impl> d_;
};

}  // namespace rehearse::app
