#pragma once
// A thin RAII layer over the SQLite C API. Every call is checked; failures throw InputError
// "<file>: <what went wrong>" with SQLite's own codes translated into words a user can act on
// ("not an SQLite database", "the file is corrupt"). Statements finalize themselves, and a
// Transaction that is not committed rolls back.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

struct sqlite3;
struct sqlite3_stmt;

namespace visloc::sqlite {

class Statement;

class Database {
 public:
  // Opens an existing file read-only; many readers may do so at once.
  static Database OpenReadOnly(const std::string& path);
  // Creates (or opens) a file for writing.
  static Database OpenForWriting(const std::string& path);

  Database(Database&& other) noexcept;
  Database& operator=(Database&& other) noexcept;
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  ~Database();

  void Exec(const std::string& sql);
  Statement Prepare(const std::string& sql);
  bool HasTable(const std::string& table);
  const std::string& path() const { return path_; }
  sqlite3* handle() const { return db_; }

  // Throws InputError for a non-OK result code `rc`, naming the file and `context`.
  void Check(int rc, const std::string& context) const;

 private:
  Database(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}
  static Database Open(const std::string& path, int flags);
  sqlite3* db_ = nullptr;
  std::string path_;
};

// A prepared statement. Bind indices are 1-based (SQLite's), column indices 0-based.
class Statement {
 public:
  Statement(Statement&& other) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  Statement& Bind(int index, int64_t value);
  Statement& Bind(int index, double value);
  Statement& Bind(int index, const std::string& value);
  // Binds raw bytes as a BLOB (copied by SQLite).
  Statement& BindBlob(int index, const void* data, size_t bytes);
  // Steps once: true when a row is available, false when done.
  bool Step();
  // Runs a statement that returns no rows, then resets it for reuse.
  void Run();
  void Reset();

  int64_t ColumnInt64(int column) const;
  double ColumnDouble(int column) const;
  std::string ColumnText(int column) const;
  // A view of a BLOB column, valid until the next Step or Reset.
  std::string_view ColumnBlob(int column) const;
  bool ColumnIsNull(int column) const;

 private:
  friend class Database;
  Statement(const Database* db, sqlite3_stmt* stmt) : db_(db), stmt_(stmt) {}
  const Database* db_;
  sqlite3_stmt* stmt_;
};

class Transaction {
 public:
  explicit Transaction(Database& db);
  ~Transaction();
  void Commit();

 private:
  Database& db_;
  bool committed_ = false;
};

}  // namespace visloc::sqlite
