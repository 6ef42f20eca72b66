// Provenance of a file OPL writes (issue 18, item 6): which tool and version
// made it, when, from which command line, and the SHA-256 of every input
// file, so that a result can be traced back and its inputs checked:
//
//   Result<Provenance> p = MakeProvenance("opl_measure", argc, argv,
//                                         {"cal.json", "spots.csv"});
//   std::string json = FormatProvenanceJson(*p);   // a JSON object, below
//   std::string csv  = FormatProvenanceComment(*p, "# ");
//
// JSON (the "provenance" member of every JSON file OPL writes; documented
// in docs/formats.md, "Provenance"):
//   {"tool": "opl_measure", "version": "0.1.0 (commit 3177915a939a)",
//    "time_utc": "2026-12-02T07:15:02Z",
//    "command_line": ["opl_measure", "--calibration", "cal.json", ...],
//    "inputs": [{"path": "cal.json", "bytes": 5120, "sha256": "9f86d0..."}]}
// Text files (CSV, PLY, XYZ) carry the same as comment lines, one field per
// line, each starting with the format's comment prefix.
//
// SHA-256 comes from OpenSSL's libcrypto (EVP), over the file's bytes as
// read in 1 MiB blocks (a 10 GB point cloud is hashed in constant memory).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "opl/core/status.h"

namespace opl {

struct InputDigest {
  std::string path;        // as named on the command line
  uint64_t bytes = 0;      // file size
  std::string sha256_hex;  // 64 lower-case hex digits
};

struct Provenance {
  std::string tool;                       // e.g. "opl_measure"
  std::string version;                    // VersionString() (core/version.h)
  std::string time_utc;                   // ISO 8601, seconds, "Z"
  std::vector<std::string> command_line;  // argv, argv[0] replaced by `tool`
  std::vector<InputDigest> inputs;        // in the order given
};

// SHA-256 of bytes in memory, 64 lower-case hex digits.
std::string Sha256Hex(std::string_view bytes);

// SHA-256 of a file's bytes, streamed. IoError "<path>: cannot open: <reason>"
// or "<path>: cannot read: <reason>" (a directory included).
Result<InputDigest> DigestFile(const std::string& path);

// The provenance of a run now: `tool`, VersionString(), the current UTC time,
// argv (argv[0] replaced by `tool`: the install path says nothing), and the
// digest of each input path (empty paths skipped; a path given twice is
// hashed once). Fails as DigestFile does.
Result<Provenance> MakeProvenance(const std::string& tool, int argc, const char* const* argv,
                                  const std::vector<std::string>& input_paths);

// The JSON object above (compact, one line; strings escaped as JSON).
std::string FormatProvenanceJson(const Provenance& provenance);

// The comment block for text files: lines "<prefix>opl <field>: <value>",
//   # opl tool: opl_measure
//   # opl version: 0.1.0 (commit 3177915a939a)
//   # opl time_utc: 2026-12-02T07:15:02Z
//   # opl command_line: opl_measure --calibration cal.json ...
//   # opl input: cal.json 5120 bytes sha256 9f86d0...
// Control characters in values are replaced by '?' so that each stays one line.
std::string FormatProvenanceComment(const Provenance& provenance, const std::string& prefix);

}  // namespace opl
