#include "sqlite/sqlite.h"

#include <sqlite3.h>

#include "core/util/check.h"

namespace visloc::sqlite {
namespace {

std::string Describe(int rc, sqlite3* db) {
  switch (rc & 0xff) {
    case SQLITE_NOTADB:
      return "not an SQLite database";
    case SQLITE_CORRUPT:
      return StrCat("the file is corrupt (", db ? sqlite3_errmsg(db) : sqlite3_errstr(rc), ")");
    case SQLITE_CANTOPEN:
      return "cannot open the file";
    case SQLITE_READONLY:
      return "the file is read-only";
    case SQLITE_FULL:
      return "the disk is full";
    default:
      return db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  }
}

}  // namespace

Database Database::Open(const std::string& path, int flags) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string message = Describe(rc, db);
    sqlite3_close(db);
    throw InputError(StrCat(path, ": ", message));
  }
  sqlite3_extended_result_codes(db, 1);
  // Corrupt files must fail loudly, never hang: wait at most 5 s for another writer's lock.
  sqlite3_busy_timeout(db, 5000);
  return Database(db, path);
}

Database Database::OpenReadOnly(const std::string& path) {
  return Open(path, SQLITE_OPEN_READONLY);
}

Database Database::OpenForWriting(const std::string& path) {
  return Open(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
}

Database::Database(Database&& other) noexcept : db_(other.db_), path_(std::move(other.path_)) {
  other.db_ = nullptr;
}

Database& Database::operator=(Database&& other) noexcept {
  if (this != &other) {
    sqlite3_close(db_);
    db_ = other.db_;
    path_ = std::move(other.path_);
    other.db_ = nullptr;
  }
  return *this;
}

Database::~Database() { sqlite3_close(db_); }

void Database::Check(int rc, const std::string& context) const {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return;
  throw InputError(
      StrCat(path_, ": ", Describe(rc, db_), context.empty() ? "" : " (" + context + ")"));
}

void Database::Exec(const std::string& sql) {
  char* error = nullptr;
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
  if (rc != SQLITE_OK) {
    const std::string message = error ? error : Describe(rc, db_);
    sqlite3_free(error);
    if ((rc & 0xff) == SQLITE_NOTADB || (rc & 0xff) == SQLITE_CORRUPT) Check(rc, "");
    throw InputError(StrCat(path_, ": ", message));
  }
}

Statement Database::Prepare(const std::string& sql) {
  sqlite3_stmt* stmt = nullptr;
  Check(sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr), "");
  return Statement(this, stmt);
}

bool Database::HasTable(const std::string& table) {
  Statement query = Prepare("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  query.Bind(1, table);
  return query.Step();
}

Statement::Statement(Statement&& other) noexcept : db_(other.db_), stmt_(other.stmt_) {
  other.stmt_ = nullptr;
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement& Statement::Bind(int index, int64_t value) {
  db_->Check(sqlite3_bind_int64(stmt_, index, value), "bind");
  return *this;
}
Statement& Statement::Bind(int index, double value) {
  db_->Check(sqlite3_bind_double(stmt_, index, value), "bind");
  return *this;
}
Statement& Statement::Bind(int index, const std::string& value) {
  db_->Check(sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()),
                               SQLITE_TRANSIENT),
             "bind");
  return *this;
}
Statement& Statement::BindBlob(int index, const void* data, size_t bytes) {
  // A zero-length BLOB must still be a BLOB, not NULL: give SQLite a valid pointer.
  static const char kEmpty = 0;
  db_->Check(sqlite3_bind_blob64(stmt_, index, bytes ? data : &kEmpty, bytes, SQLITE_TRANSIENT),
             "bind");
  return *this;
}

bool Statement::Step() {
  const int rc = sqlite3_step(stmt_);
  db_->Check(rc, "");
  return rc == SQLITE_ROW;
}

void Statement::Run() {
  while (Step()) {
  }
  Reset();
}

void Statement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int64_t Statement::ColumnInt64(int column) const { return sqlite3_column_int64(stmt_, column); }
double Statement::ColumnDouble(int column) const { return sqlite3_column_double(stmt_, column); }
std::string Statement::ColumnText(int column) const {
  const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, column));
  return text ? std::string(text, sqlite3_column_bytes(stmt_, column)) : std::string();
}
std::string_view Statement::ColumnBlob(int column) const {
  const void* data = sqlite3_column_blob(stmt_, column);
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return data ? std::string_view(static_cast<const char*>(data), bytes) : std::string_view();
}
bool Statement::ColumnIsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

Transaction::Transaction(Database& db) : db_(db) { db_.Exec("BEGIN IMMEDIATE"); }

Transaction::~Transaction() {
  if (!committed_) sqlite3_exec(db_.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
}

void Transaction::Commit() {
  db_.Exec("COMMIT");
  committed_ = true;
}

}  // namespace visloc::sqlite
