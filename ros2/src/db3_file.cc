// rosbag2's sqlite3 storage (.db3), read-only (storage.h).
#include <sqlite3.h>

#include <string>
#include <utility>

#include "storage.h"

namespace sfrt::ros2 {
namespace {

struct CloseDatabase {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};
struct FinalizeStatement {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Database = std::unique_ptr<sqlite3, CloseDatabase>;
using Statement = std::unique_ptr<sqlite3_stmt, FinalizeStatement>;

std::string Text(sqlite3_stmt* s, int column) {
  const unsigned char* text = sqlite3_column_text(s, column);
  return text == nullptr ? std::string() : reinterpret_cast<const char*>(text);
}

class Db3File final : public StorageFile {
 public:
  Status Open(const std::string& path) override {
    path_ = path;
    sqlite3* db = nullptr;
    const int rc = sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
    db_.reset(db);  // closed even when the open failed
    if (rc != SQLITE_OK) return Error("cannot open it as an sqlite3 database", rc);
    if (Status s = ReadTopics(); !s.ok()) return s;
    return CountMessages();
  }

  const std::vector<StoredTopic>& topics() const override { return topics_; }

  Status Select(const std::vector<size_t>& topics) override {
    std::string ids;
    for (size_t t : topics) {
      if (t >= topics_.size())
        return Status::Error("'" + path_ + "': no topic " + std::to_string(t));
      ids += (ids.empty() ? "" : ",") + std::to_string(ids_[t]);
    }
    // The ids are integers read from the file itself, so the text holds no quote or operator.
    const std::string sql = "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN (" +
                            ids + ") ORDER BY timestamp, id";
    Result<Statement> prepared = Prepare(sql);
    if (!prepared.ok()) return prepared.status();
    read_ = std::move(prepared).value();
    return Status::Ok();
  }

  Result<bool> Next(StoredMessage* out) override {
    if (!read_) return Status::Error("'" + path_ + "': Next() before Select()");
    const int rc = sqlite3_step(read_.get());
    if (rc == SQLITE_DONE) return false;
    if (rc != SQLITE_ROW) return Error("cannot read the next message", rc);
    const int64_t id = sqlite3_column_int64(read_.get(), 0);
    size_t topic = 0;
    while (topic < ids_.size() && ids_[topic] != id) ++topic;
    if (topic == ids_.size()) {
      return Status::Error("'" + path_ + "': a message on topic id " + std::to_string(id) +
                           ", which the topics table does not hold");
    }
    out->topic = topic;
    out->receive_ns = sqlite3_column_int64(read_.get(), 1);
    out->file_offset = -1;
    // The blob first, then its size: the order sqlite3 documents for a stable pointer.
    out->data = static_cast<const uint8_t*>(sqlite3_column_blob(read_.get(), 2));
    const int size = sqlite3_column_bytes(read_.get(), 2);
    out->size = size > 0 ? static_cast<size_t>(size) : 0;
    return true;
  }

 private:
  Status Error(const std::string& what, int rc) const {
    const char* detail = db_ ? sqlite3_errmsg(db_.get()) : sqlite3_errstr(rc);
    return Status::Error("'" + path_ + "': " + what + " (sqlite3: " + detail + ")");
  }

  Result<Statement> Prepare(const std::string& sql) {
    sqlite3_stmt* s = nullptr;
    const int rc = sqlite3_prepare_v2(db_.get(), sql.c_str(), -1, &s, nullptr);
    Statement statement(s);
    if (rc != SQLITE_OK) {
      return Error("not a rosbag2 sqlite3 bag: cannot run '" + sql + "'", rc);
    }
    return statement;
  }

  Status ReadTopics() {
    Result<Statement> s =
        Prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id");
    if (!s.ok()) return s.status();
    int rc;
    while ((rc = sqlite3_step(s->get())) == SQLITE_ROW) {
      ids_.push_back(sqlite3_column_int64(s->get(), 0));
      StoredTopic topic;
      topic.name = Text(s->get(), 1);
      topic.type = Text(s->get(), 2);
      topic.serialization_format = Text(s->get(), 3);
      topics_.push_back(std::move(topic));
    }
    if (rc != SQLITE_DONE) return Error("cannot read its topics table", rc);
    return Status::Ok();
  }

  Status CountMessages() {
    Result<Statement> s = Prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id");
    if (!s.ok()) return s.status();
    for (StoredTopic& t : topics_) t.messages = 0;
    int rc;
    while ((rc = sqlite3_step(s->get())) == SQLITE_ROW) {
      const int64_t id = sqlite3_column_int64(s->get(), 0);
      for (size_t t = 0; t < ids_.size(); ++t) {
        if (ids_[t] == id) topics_[t].messages = sqlite3_column_int64(s->get(), 1);
      }
    }
    if (rc != SQLITE_DONE) return Error("cannot count its messages", rc);
    return Status::Ok();
  }

  std::string path_;
  Database db_;
  std::vector<StoredTopic> topics_;
  std::vector<int64_t> ids_;  // each topic's id in the file
  Statement read_;
};

}  // namespace

std::unique_ptr<StorageFile> MakeDb3File() { return std::make_unique<Db3File>(); }

}  // namespace sfrt::ros2
