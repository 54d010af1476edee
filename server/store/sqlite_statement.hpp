// A prepared SQLite statement, for the store's SQLite code (internal to the store
// library): binds, steps and reads columns; every failure a StoreError naming the store.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <span>
#include <string>

#include "server/store/world_store.hpp"

namespace vox::store {

// A prepared statement. Made from SQL it is its own, finalized at the end; made from a
// statement of the connection's cache (StatementCache) it is borrowed, and only reset.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::string& name) : name_(name) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK)
      throw StoreError(name_ + ": " + sqlite3_errmsg(db));
  }
  Statement(sqlite3_stmt* cached, const std::string& name)
      : stmt_(cached), name_(name), owned_(false) {}
  ~Statement() {
    if (owned_)
      sqlite3_finalize(stmt_);
    else
      reset();
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& bind(int i, int64_t v) {
    check(sqlite3_bind_int64(stmt_, i, v));
    return *this;
  }
  Statement& bind(int i, const std::string& v) {
    check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& bind(int i, std::span<const uint8_t> v) {
    check(sqlite3_bind_blob(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  // True while there is a row.
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw StoreError(name_ + ": " + sqlite3_errmsg(sqlite3_db_handle(stmt_)));
  }
  void run() {
    while (step()) {
    }
    reset();
  }
  void reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  bool is_integer(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_INTEGER; }
  std::string text(int col) const {
    const auto* p = sqlite3_column_text(stmt_, col);
    return p ? std::string(reinterpret_cast<const char*>(p),
                           static_cast<size_t>(sqlite3_column_bytes(stmt_, col)))
             : std::string();
  }
  std::span<const uint8_t> blob(int col) const {
    const auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(stmt_, col));
    return {p, static_cast<size_t>(sqlite3_column_bytes(stmt_, col))};
  }

 private:
  void check(int rc) {
    if (rc != SQLITE_OK) throw StoreError(name_ + ": " + sqlite3_errstr(rc));
  }
  sqlite3_stmt* stmt_ = nullptr;
  const std::string& name_;
  bool owned_ = true;
};

}  // namespace vox::store
