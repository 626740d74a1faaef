#pragma once
// The recordings' SQLite store, shared by the recorder (recorder.cpp), the loaders and the copying
// (recording_store.cpp): its schema, prepared statements and small helpers. Internal to app core.
#include <sqlite3.h>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace rehearse::app::detail {

/// Now as ISO 8601 UTC ("2026-11-25T21:06:31Z").
std::string utcNow();

/// One prepared statement, finalised on every path.
struct Statement {
  sqlite3_stmt* s = nullptr;
  Statement(sqlite3* db, const char* sql) {
    if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("the recording store cannot be read: ") + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(s); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void text(int i, const std::string& v) {
    sqlite3_bind_text(s, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  std::string column(int i) const {
    const auto* t = sqlite3_column_text(s, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
};

/// How a file is opened to be read: read-write (never created) where this process may write the file and its folder,
/// read-only elsewhere. A file recorded into is in WAL mode, and a read-only connection can neither checkpoint nor
/// remove the -wal and -shm files it makes beside it: a listing or a replay left them next to the user's case.
int readingFlags(const std::string& path);
/// Opens the store (read-write and created when `create`, else as readingFlags says); throws a sentence.
sqlite3* openStore(const std::string& path, bool create);
/// A session's checksum after `step` through `q` (INSERT, or INSERT OR IGNORE when written again).
void writeChecksum(sqlite3* db, Statement& q, std::int64_t session, long step, std::uint64_t sum);
bool hasTable(sqlite3* db, const char* name);
/// The schema, and the uuid column added to a file recorded before it existed (its sessions get one).
void ensureSchema(sqlite3* db);

}  // namespace rehearse::app::detail
