// Atomic file output: a file is either written completely or not at all.
//
// WriteFileAtomically(path, contents) writes `contents` to a new temporary file
// in the directory of `path` (named ".<name>.tmp-<pid>-<n>", created with
// O_EXCL and mode 0666 & ~umask, or with the mode of the file it replaces),
// fsyncs it, renames it over `path` (atomic on POSIX file systems) and fsyncs
// the directory. On any failure the temporary file is removed, `path` is left
// as it was (absent or with its old contents) and an IoError names the path
// and the system error, e.g.
//   "out/spots.csv: cannot write: cannot create a temporary file in 'out':
//    No such file or directory"
// Readers never observe a partially written file.
#pragma once

#include <string>

#include "opl/core/status.h"

namespace opl {

Status WriteFileAtomically(const std::string& path, const std::string& contents);

// Reads a whole file. IoError "<path>: cannot open: <reason>" on failure
// (missing, unreadable), "<path>: cannot read: is a directory".
Result<std::string> ReadFileToString(const std::string& path);

}  // namespace opl
