// All of a run's outputs or none (developers' brief; issue 19, item 2; issue
// 18, item 6): a tool stages every file it will write, and they appear
// together at Commit(), each stamped with the run's provenance.
//
//   OutputSet out(provenance);                  // io/provenance.h
//   OPL_RETURN_IF_ERROR(out.Add("result.json", json));
//   OPL_RETURN_IF_ERROR(out.Add("spots.csv", csv));
//   OPL_RETURN_IF_ERROR(out.Commit());
//
// Add() stamps the contents (StampProvenance: by the file's extension) and
// writes them at once to a temporary file beside the path, fsynced: a full
// disk, a missing folder or a read-only folder fails here, before any output
// is replaced. Commit() then renames every temporary file over its path. A
// path that already held a file is first hard-linked to a backup name, so
// that if a later rename fails the files already replaced get their old
// contents back, the new ones are removed, and the error names the file; the
// backups are removed after a successful commit. (On a file system without
// hard links an old file cannot be restored after a failed rename; renames in
// the folder the temporary file was just written to fail in practice only
// when a folder has taken the output's name, which Add() also checks.)
// Destroying an uncommitted set (an error return) removes its temporary
// files: nothing is written.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/atomic_file.h"
#include "opl/io/provenance.h"

namespace opl {

class OutputSet {
 public:
  OutputSet() = default;  // no provenance stamp (library tests, scratch files)
  explicit OutputSet(Provenance provenance) : provenance_(std::move(provenance)) {}
  ~OutputSet();  // Abandon() unless committed
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  // Stages `contents` for `path` (stamped when the set has a provenance).
  // Refused: a path staged twice, a path that is a folder, and what
  // StampProvenance refuses (an extension it has no comment syntax for).
  Status Add(const std::string& path, const std::string& contents);
  // The same without the stamp: bytes written exactly as given (a file whose
  // format has no place for it, e.g. a copied input).
  Status AddVerbatim(const std::string& path, const std::string& contents);

  // A file too large to hold in memory (a point cloud), streamed by the
  // caller: the writer is open on a temporary file beside `path`; the caller
  // writes (stamping it itself: StampProvenance needs the whole text) and
  // calls Finish() on it, or Commit() fails naming the file. Owned by the set.
  Result<AtomicFileWriter*> AddStreamed(const std::string& path);

  // Makes every staged file appear (see above). Once only.
  Status Commit();
  // Removes every temporary file; no path is touched.
  void Abandon();

  size_t size() const { return writers_.size(); }
  const std::optional<Provenance>& provenance() const { return provenance_; }

 private:
  std::optional<Provenance> provenance_;
  std::vector<std::unique_ptr<AtomicFileWriter>> writers_;
  bool committed_ = false;
};

}  // namespace opl
