#include "opl/io/scale_point_file.h"

#include <cmath>

#include "io/csv.h"
#include "io/point_file_stream.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

using point_file_internal::InputFile;
using point_file_internal::OutputBuffer;
using point_file_internal::ScaleCounts;

constexpr int64_t kMinBufferBytes = 4096;
constexpr int64_t kMaxBufferBytes = int64_t{1} << 30;

Status Dispatch(PointFileFormat format, InputFile& in, OutputBuffer* out, double s,
                bool header_only, ScaleCounts* counts, const Provenance* provenance = nullptr) {
  if (provenance != nullptr && !header_only && format != PointFileFormat::kPly) {
    out->Append(FormatProvenanceComment(*provenance, "# "));
  }
  switch (format) {
    case PointFileFormat::kPly:
      return point_file_internal::ScalePly(
          in, out, s, header_only, counts,
          provenance != nullptr ? FormatProvenanceComment(*provenance, "comment ") : "");
    case PointFileFormat::kXyz:
      return point_file_internal::ScaleXyz(in, out, s, header_only, counts);
    case PointFileFormat::kCsv:
      return point_file_internal::ScaleCsv(in, out, s, header_only, counts);
    case PointFileFormat::kAuto: break;
  }
  return Status::InvalidArgument("no point file format");
}

// Options checked, format resolved, input opened.
Status Prepare(const std::string& in_path, const ScalePointFileOptions& options,
               PointFileFormat* format, InputFile* in) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  OPL_RETURN_IF_ERROR(in->Open(in_path, static_cast<size_t>(options.buffer_bytes)));
  *format = options.format;
  if (*format == PointFileFormat::kAuto) {
    Result<PointFileFormat> from_path = PointFileFormatFromPath(in_path);
    if (!from_path.ok()) return from_path.status();
    *format = *from_path;
  }
  in->progress = options.progress;
  return Status::Ok();
}

}  // namespace

const char* PointFileFormatName(PointFileFormat format) {
  switch (format) {
    case PointFileFormat::kAuto: return "auto";
    case PointFileFormat::kPly: return "ply";
    case PointFileFormat::kXyz: return "xyz";
    case PointFileFormat::kCsv: return "csv";
  }
  return "?";
}

Result<PointFileFormat> ParsePointFileFormat(const std::string& name) {
  for (PointFileFormat f : {PointFileFormat::kAuto, PointFileFormat::kPly, PointFileFormat::kXyz,
                            PointFileFormat::kCsv}) {
    if (name == PointFileFormatName(f)) return f;
  }
  return Status::InvalidArgument("unknown point file format '" + name +
                                 "' (auto, ply, xyz or csv)");
}

Result<PointFileFormat> PointFileFormatFromPath(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = name.find_last_of('.');
  const std::string extension =
      dot == std::string::npos || dot == 0 ? std::string() : csv_internal::Lower(name.substr(dot));
  if (extension == ".ply") return PointFileFormat::kPly;
  if (extension == ".xyz" || extension == ".txt") return PointFileFormat::kXyz;
  if (extension == ".csv") return PointFileFormat::kCsv;
  return Status::InvalidArgument(
      path + ": cannot tell the point file format from the " +
      (extension.empty() ? std::string("name (no extension)")
                         : "extension '" + name.substr(dot) + "'") +
      " (.ply, .xyz, .txt or .csv; or give the format)");
}

bool ScalePointFileOptions::IsValid(std::string* why) const {
  if (buffer_bytes < kMinBufferBytes || buffer_bytes > kMaxBufferBytes) {
    if (why) {
      *why = "ScalePointFileOptions::buffer_bytes must be in [4096, 2^30], got " +
             std::to_string(buffer_bytes);
    }
    return false;
  }
  return true;
}

std::string ScalePointFileSummary::BriefReport() const {
  return std::to_string(num_points) + " points (" + PointFileFormatName(format) + ") scaled, " +
         std::to_string(bytes_written) + " bytes written";
}

Status ScalePointFile(const std::string& in_path, const std::string& out_path, double s,
                      const ScalePointFileOptions& options, ScalePointFileSummary* summary) {
  ScalePointFileSummary local;
  ScalePointFileSummary& sum = summary ? *summary : local;
  sum = ScalePointFileSummary();
  if (!(std::isfinite(s) && s > 0.0)) {
    return Status::InvalidArgument("scale factor must be finite and > 0, got " +
                                   FormatRoundTrip(s));
  }
  InputFile in;
  OPL_RETURN_IF_ERROR(Prepare(in_path, options, &sum.format, &in));
  // The header first: a bad input fails before an output file is created.
  ScaleCounts counts;
  {
    InputFile probe;
    OPL_RETURN_IF_ERROR(probe.Open(in_path, static_cast<size_t>(options.buffer_bytes)));
    OutputBuffer discard(nullptr, kMinBufferBytes);
    OPL_RETURN_IF_ERROR(Dispatch(sum.format, probe, &discard, s, true, &counts));
  }
  AtomicFileWriter own_writer;
  AtomicFileWriter* writer = &own_writer;
  if (options.outputs != nullptr) {
    Result<AtomicFileWriter*> staged = options.outputs->AddStreamed(out_path);
    if (!staged.ok()) {
      sum.output_failed = true;
      return staged.status();
    }
    writer = *staged;
  } else if (Status st = own_writer.Open(out_path); !st.ok()) {
    sum.output_failed = true;
    return st;
  }
  OutputBuffer out(writer, static_cast<size_t>(options.buffer_bytes));
  Status st = Dispatch(sum.format, in, &out, s, false, &counts, options.provenance);
  if (st.ok()) out.Flush();
  if (st.ok() && out.failed()) {
    sum.output_failed = true;
    return out.status();  // the writer has removed its temporary file
  }
  if (!st.ok()) {
    writer->Abandon();  // (own_writer's destructor would too; a staged one is the set's)
    return st;
  }
  if (Status commit = options.outputs != nullptr ? writer->Finish() : writer->Commit();
      !commit.ok()) {
    sum.output_failed = true;
    return commit;
  }
  sum.num_points = counts.num_points;
  sum.bytes_read = in.offset() + static_cast<int64_t>(in.size());
  sum.bytes_written = writer->bytes_written();
  return Status::Ok();
}

Status CheckPointFile(const std::string& in_path, const ScalePointFileOptions& options) {
  InputFile in;
  PointFileFormat format;
  OPL_RETURN_IF_ERROR(Prepare(in_path, options, &format, &in));
  ScaleCounts counts;
  OutputBuffer discard(nullptr, kMinBufferBytes);
  return Dispatch(format, in, &discard, 1.0, true, &counts);
}

}  // namespace opl
