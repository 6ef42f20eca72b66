#include "opl/io/output_set.h"

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

#include "opl/io/provenance_stamp.h"

namespace opl {
namespace {

// A fresh name beside `path` for the old file's backup while committing.
std::string BackupName(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const size_t slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "" : path.substr(0, slash + 1);
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  return dir + "." + name + ".old-" + std::to_string(::getpid()) + "-" +
         std::to_string(counter++);
}

}  // namespace

OutputSet::~OutputSet() {
  if (!committed_) Abandon();
}

Status OutputSet::Add(const std::string& path, const std::string& contents) {
  if (!provenance_) return AddVerbatim(path, contents);
  Result<std::string> stamped = StampProvenance(path, contents, *provenance_);
  if (!stamped.ok()) return stamped.status();
  return AddVerbatim(path, *stamped);
}

Status OutputSet::AddVerbatim(const std::string& path, const std::string& contents) {
  Result<AtomicFileWriter*> writer = AddStreamed(path);
  if (!writer.ok()) return writer.status();
  OPL_RETURN_IF_ERROR((*writer)->Write(contents.data(), contents.size()));
  return (*writer)->Finish();
}

Result<AtomicFileWriter*> OutputSet::AddStreamed(const std::string& path) {
  if (committed_) return Status::IoError(path + ": cannot write: the output set is committed");
  for (const auto& writer : writers_) {
    if (writer->path() == path) {
      return Status::InvalidArgument(path + ": cannot write: named twice among the outputs");
    }
  }
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
    return Status::IoError(path + ": cannot write: is a directory");
  }
  auto writer = std::make_unique<AtomicFileWriter>();
  OPL_RETURN_IF_ERROR(writer->Open(path));
  writers_.push_back(std::move(writer));
  return writers_.back().get();
}

Status OutputSet::Commit() {
  if (committed_) return Status::IoError("outputs: already committed");
  for (const auto& writer : writers_) {
    if (writer->is_open()) {
      const std::string path = writer->path();
      Abandon();
      return Status::IoError(path + ": cannot write: the streamed file was not finished");
    }
  }
  // Backups of the files about to be replaced ("" where none was).
  std::vector<std::string> backups(writers_.size());
  std::vector<bool> existed(writers_.size(), false);
  const auto remove_backups = [&backups]() {
    for (const std::string& b : backups) {
      if (!b.empty()) ::unlink(b.c_str());
    }
  };
  for (size_t i = 0; i < writers_.size(); ++i) {
    const std::string& path = writers_[i]->path();
    struct stat st;
    if (::lstat(path.c_str(), &st) != 0) continue;
    existed[i] = true;
    if (S_ISDIR(st.st_mode)) {
      remove_backups();
      Abandon();
      return Status::IoError(path + ": cannot write: is a directory");
    }
    const std::string backup = BackupName(path);
    if (::link(path.c_str(), backup.c_str()) == 0) backups[i] = backup;
  }
  for (size_t i = 0; i < writers_.size(); ++i) {
    Status published = writers_[i]->Publish();
    if (published.ok()) continue;
    // Undo: the files already replaced get their old contents back (or go).
    for (size_t k = 0; k < i; ++k) {
      const std::string& path = writers_[k]->path();
      if (!backups[k].empty()) {
        if (::rename(backups[k].c_str(), path.c_str()) == 0) backups[k].clear();
      } else if (!existed[k]) {
        ::unlink(path.c_str());
      }  // else: an old file without a backup (no hard links) keeps the new contents
    }
    remove_backups();
    Abandon();
    return published;
  }
  remove_backups();
  committed_ = true;
  return Status::Ok();
}

void OutputSet::Abandon() {
  for (auto& writer : writers_) writer->Abandon();
  writers_.clear();
}

}  // namespace opl
