// The case file's parts shared by its writer (casefile_save.cpp) and its reader (casefile_load.cpp): the database
// connection, the checksums, and the words and JSON shapes both directions use. Internal to the application core.
#pragma once

#include <rehearse/app/case.hpp>
#include <rehearse/types.hpp>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::app::casefile_parts {

[[noreturn]] void fail(const std::string& message);
std::string fileName(const std::string& path);
// Why SQLite failed, in our words (its own text, e.g. "unable to open database file", names no cause a user can act
// on). `code` is SQLite's result code (primary or extended).
std::string sqlProblem(int code);
std::string sha256(const std::string& data);
// Now as ISO 8601 UTC with milliseconds ("2026-11-30T14:25:01.123Z"), as the case files have always said.
std::string utcNowWithMs();
std::string exactNumber(double v);
void fsyncPath(const std::string& path, int flags);
nlohmann::json poseJson(const Pose& p);
Pose poseFrom(const nlohmann::json& j);
nlohmann::json vec(const Eigen::Vector3d& v);
Eigen::Vector3d vec3(const nlohmann::json& j);
// The case file's words for where gravity points (material.json's "gravity").
const char* gravityWord(GravityChoice g);

// One database connection, closed on every path; statements run to completion one at a time.
class Database {
 public:
  Database(const std::string& path, int flags) {
    code_ = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
    if (code_ == SQLITE_OK) sqlite3_extended_result_codes(db_, 1), sqlite3_busy_timeout(db_, 2000);
  }
  ~Database() { sqlite3_close(db_); }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  bool open() const { return code_ == SQLITE_OK; }
  int code() const { return code_; }
  // Runs `sql` (no result rows wanted); false with code() set when SQLite refused.
  bool exec(const char* sql) {
    code_ = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
    return code_ == SQLITE_OK;
  }
  // Inserts one row of `texts` then `blobs` (bound in that order) through `sql`.
  bool insert(const char* sql, std::initializer_list<const std::string*> texts,
              std::initializer_list<const std::string*> blobs) {
    sqlite3_stmt* s = nullptr;
    code_ = sqlite3_prepare_v2(db_, sql, -1, &s, nullptr);
    if (code_ != SQLITE_OK) return false;
    int i = 1;
    for (const std::string* t : texts) sqlite3_bind_text64(s, i++, t->data(), t->size(), SQLITE_STATIC, SQLITE_UTF8);
    for (const std::string* b : blobs) sqlite3_bind_blob64(s, i++, b->data(), b->size(), SQLITE_STATIC);
    code_ = sqlite3_step(s);
    sqlite3_finalize(s);
    if (code_ == SQLITE_DONE) code_ = SQLITE_OK;
    return code_ == SQLITE_OK;
  }
  // The first row's columns of `sql` with `key` bound, as bytes; nullopt when there is no row or SQLite refused
  // (then code() says why).
  std::optional<std::vector<std::string>> row(const char* sql, const std::string& key, int columns) {
    sqlite3_stmt* s = nullptr;
    code_ = sqlite3_prepare_v2(db_, sql, -1, &s, nullptr);
    if (code_ != SQLITE_OK) return std::nullopt;
    sqlite3_bind_text64(s, 1, key.data(), key.size(), SQLITE_STATIC, SQLITE_UTF8);
    std::optional<std::vector<std::string>> out;
    code_ = sqlite3_step(s);
    if (code_ == SQLITE_ROW) {
      code_ = SQLITE_OK;
      out.emplace();
      for (int k = 0; k < columns; ++k) {
        const auto* p = static_cast<const char*>(sqlite3_column_blob(s, k));
        out->emplace_back(p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(s, k))) : std::string());
      }
    } else if (code_ == SQLITE_DONE) {
      code_ = SQLITE_OK;
    }
    sqlite3_finalize(s);
    return out;
  }
  std::optional<std::string> meta(const std::string& key) {
    auto r = row("SELECT value FROM meta WHERE key = ?", key, 1);
    if (!r) return std::nullopt;
    return r->front();
  }

 private:
  sqlite3* db_ = nullptr;
  int code_ = SQLITE_OK;
};

}  // namespace rehearse::app::casefile_parts
