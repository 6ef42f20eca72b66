#include "opl/sim/pattern_models.h"

#include "opl/core/format.h"
#include "opl/core/message_text.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "opl/geometry/spherical.h"

namespace opl {
namespace {

// Lattice coordinates of beam `id`: (i, j) = (c - m, m - r).
void LatticeOf(int id, int n, int* i, int* j) {
  const int m = (n - 1) / 2;
  *i = BeamCol(id, n) - m;
  *j = m - BeamRow(id, n);
}

std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t' || s[b] == '\r')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r')) --e;
  return s.substr(b, e - b);
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) out.push_back(Trim(field));
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

bool ParseDouble(const std::string& s, double* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && errno != ERANGE && std::isfinite(*v);
}

bool ParseInt(const std::string& s, int* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const long x = std::strtol(s.c_str(), &end, 10);
  if (end != s.c_str() + s.size() || errno == ERANGE || x < std::numeric_limits<int>::min() ||
      x > std::numeric_limits<int>::max()) {
    return false;
  }
  *v = static_cast<int>(x);
  return true;
}

// Grating beams at `actual` wavelength for a period designed at `design`.
// Returns false if a beam is evanescent.
bool GratingBeams(int n, double full_angle_rad, double design_nm, double actual_nm,
                  std::vector<Beam>* beams) {
  const int m = (n - 1) / 2;
  // lambda / period = sin(full/2) / m at the design wavelength.
  const double step = std::sin(0.5 * full_angle_rad) / m * (actual_nm / design_nm);
  beams->clear();
  beams->reserve(static_cast<size_t>(n) * n);
  for (int id = 1; id <= n * n; ++id) {
    int i = 0, j = 0;
    LatticeOf(id, n, &i, &j);
    const double ky = i * step;
    const double kz = j * step;
    const double kx2 = 1.0 - ky * ky - kz * kz;
    if (!(kx2 > 0.0)) return false;
    const Eigen::Vector3d k(std::sqrt(kx2), ky, kz);
    Beam b;
    b.id = id;
    b.az_rad = AzimuthRad(k);
    b.el_rad = ElevationRad(k);
    beams->push_back(b);
  }
  return true;
}

}  // namespace

const char* PatternModelName(PatternModel model) {
  switch (model) {
    case PatternModel::kEqualAngle: return "equal_angle";
    case PatternModel::kGrating: return "grating";
    case PatternModel::kFile: return "file";
  }
  return "unknown";
}

Status CheckPatternParameters(PatternModel model, int beams_per_side, double full_angle_rad,
                              double wavelength_nm) {
  if (model == PatternModel::kFile) return Status::Ok();
  OPL_RETURN_IF_ERROR(CheckBeamsPerSide(beams_per_side));
  const double max_rad = model == PatternModel::kGrating ? 0.5 * kPi : kPi;
  if (!(std::isfinite(full_angle_rad) && full_angle_rad > 0.0 && full_angle_rad < max_rad)) {
    return Status::InvalidArgument(
        std::string("full angle must be finite, > 0 and < ") +
        (model == PatternModel::kGrating ? "90 deg for a grating (corner orders must propagate)"
                                         : "180 deg") +
        ", got " + FormatNumber(full_angle_rad * 180.0 / kPi) + " deg");
  }
  if (model == PatternModel::kGrating) {
    if (!(std::isfinite(wavelength_nm) && wavelength_nm > 0.0)) {
      return Status::InvalidArgument("wavelength_nm must be finite and > 0, got " +
                                     FormatNumber(wavelength_nm));
    }
  }
  return Status::Ok();
}

BeamPattern MakeEqualAnglePattern(int beams_per_side, double full_angle_rad) {
  if (!CheckPatternParameters(PatternModel::kEqualAngle, beams_per_side, full_angle_rad, 1.0)
           .ok()) {
    return BeamPattern();
  }
  const int n = beams_per_side;
  const int m = (n - 1) / 2;
  const double half = 0.5 * full_angle_rad;
  std::vector<Beam> beams;
  beams.reserve(static_cast<size_t>(n) * n);
  for (int id = 1; id <= n * n; ++id) {
    int i = 0, j = 0;
    LatticeOf(id, n, &i, &j);
    // Direction (1, tan(i theta0), tan(j theta0)):
    //   az = atan2(tan(i theta0), 1) = i theta0 exactly (|i theta0| < pi/2),
    //   el = atan2(tan(j theta0), hypot(1, tan(i theta0))) = atan(tan(j theta0) cos(i theta0)).
    // Written as half * (i / m) so that the outermost beams are at exactly +-half.
    const double a = half * (static_cast<double>(i) / m);
    const double b = half * (static_cast<double>(j) / m);
    Beam beam;
    beam.id = id;
    beam.az_rad = a;
    beam.el_rad = j == 0 ? 0.0 : (i == 0 ? b : std::atan(std::tan(b) * std::cos(a)));
    beams.push_back(beam);
  }
  return BeamPattern(n, std::move(beams));
}

BeamPattern MakeGratingPattern(int beams_per_side, double full_angle_rad, double wavelength_nm) {
  return MakeGratingPatternAtWavelength(beams_per_side, full_angle_rad, wavelength_nm,
                                        wavelength_nm);
}

BeamPattern MakeGratingPatternAtWavelength(int beams_per_side, double full_angle_rad,
                                           double design_wavelength_nm,
                                           double actual_wavelength_nm) {
  if (!CheckPatternParameters(PatternModel::kGrating, beams_per_side, full_angle_rad,
                              design_wavelength_nm)
           .ok() ||
      !(std::isfinite(actual_wavelength_nm) && actual_wavelength_nm > 0.0)) {
    return BeamPattern();
  }
  std::vector<Beam> beams;
  if (!GratingBeams(beams_per_side, full_angle_rad, design_wavelength_nm, actual_wavelength_nm,
                    &beams)) {
    return BeamPattern();
  }
  return BeamPattern(beams_per_side, std::move(beams));
}

double GratingPeriodNm(int beams_per_side, double full_angle_rad, double wavelength_nm) {
  if (!CheckPatternParameters(PatternModel::kGrating, beams_per_side, full_angle_rad,
                              wavelength_nm)
           .ok()) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const int m = (beams_per_side - 1) / 2;
  return m * wavelength_nm / std::sin(0.5 * full_angle_rad);
}

Eigen::Matrix<double, Eigen::Dynamic, 2> GratingDAzElDWavelength(int beams_per_side,
                                                                 double full_angle_rad,
                                                                 double wavelength_nm) {
  Eigen::Matrix<double, Eigen::Dynamic, 2> d(0, 2);
  if (!CheckPatternParameters(PatternModel::kGrating, beams_per_side, full_angle_rad,
                              wavelength_nm)
           .ok()) {
    return d;
  }
  const int n = beams_per_side;
  const int m = (n - 1) / 2;
  const double step = std::sin(0.5 * full_angle_rad) / m;  // lambda / period
  d.resize(n * n, 2);
  for (int id = 1; id <= n * n; ++id) {
    int i = 0, j = 0;
    LatticeOf(id, n, &i, &j);
    const double ky = i * step;
    const double kz = j * step;
    const double kx = std::sqrt(1.0 - ky * ky - kz * kz);
    const double one_minus_kz2 = 1.0 - kz * kz;
    // k_y = i lambda / p, k_z = j lambda / p: d k_y/d lambda = k_y / lambda, same for k_z;
    // d k_x / d lambda = -(k_y^2 + k_z^2) / (lambda k_x).
    // el = asin(k_z)         -> d el = dk_z / sqrt(1 - k_z^2)
    // az = atan2(k_y, k_x)   -> d az = (k_x dk_y - k_y dk_x) / (k_x^2 + k_y^2)
    //                                 = k_y / (lambda k_x (1 - k_z^2))
    d(id - 1, 0) = ky / (wavelength_nm * kx * one_minus_kz2);
    d(id - 1, 1) = kz / (wavelength_nm * std::sqrt(one_minus_kz2));
  }
  return d;
}

Result<BeamPattern> ReadPatternCsv(const std::string& path) {
  // A regular file of bounded size only: a pattern_file of /dev/zero read
  // forever (its one "line" never ends).
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    return Status::IoError(path + ": cannot open pattern file");
  }
  if (!std::filesystem::is_regular_file(status)) {
    return Status::IoError(path + ": cannot read pattern file: not a regular file");
  }
  const auto bytes = std::filesystem::file_size(path, ec);
  if (ec) return Status::IoError(path + ": cannot open pattern file");
  if (bytes > static_cast<std::uintmax_t>(kMaxPatternFileBytes)) {
    return Status::IoError(path + ": cannot read pattern file: " + std::to_string(bytes) +
                           " bytes, more than the " + std::to_string(kMaxPatternFileBytes) +
                           " a pattern file may have (201 x 201 beams need a few MB)");
  }
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot open pattern file");
  int beams_per_side = 0;
  int beams_per_side_line = 0;
  int col_id = -1, col_az = -1, col_el = -1;
  size_t num_columns = 0;
  bool have_header = false;
  std::vector<Beam> beams;
  std::map<int, int> line_of_id;
  std::string line;
  int line_no = 0;
  auto where = [&](int l) { return path + ":" + std::to_string(l) + ": "; };
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = Trim(line);
    if (t.empty()) continue;
    if (t[0] == '#') {
      const std::string body = Trim(t.substr(1));
      const std::string key = "beams_per_side";
      if (body.compare(0, key.size(), key) == 0) {
        std::string rest = Trim(body.substr(key.size()));
        if (rest.empty() || rest[0] != ':') {
          return Status::ParseError(where(line_no) + "expected '# beams_per_side: N'");
        }
        rest = Trim(rest.substr(1));
        if (have_header) {
          return Status::ParseError(where(line_no) +
                                    "'# beams_per_side' must come before the header line");
        }
        if (beams_per_side_line > 0) {
          return Status::ParseError(where(line_no) + "'# beams_per_side' given twice (first on line " +
                                    std::to_string(beams_per_side_line) + ")");
        }
        int n = 0;
        if (!ParseInt(rest, &n) || !BeamsPerSideProblem(n).empty()) {
          return Status::ParseError(where(line_no) + "beams_per_side must be an odd integer in [3, " +
                                    std::to_string(kMaxBeamsPerSide) + "], got " +
                                    QuoteForMessage(rest, 40));
        }
        beams_per_side = n;
        beams_per_side_line = line_no;
      }
      continue;
    }
    const std::vector<std::string> fields = SplitCsv(t);
    if (!have_header) {
      for (size_t k = 0; k < fields.size(); ++k) {
        int* target = fields[k] == "id"       ? &col_id
                      : fields[k] == "az_rad" ? &col_az
                      : fields[k] == "el_rad" ? &col_el
                                              : nullptr;
        if (target == nullptr) continue;
        if (*target >= 0) {
          return Status::ParseError(where(line_no) + "column " + QuoteForMessage(fields[k], 40) +
                                    " appears twice");
        }
        *target = static_cast<int>(k);
      }
      for (const auto& [name, col] : {std::pair<const char*, int>{"id", col_id},
                                     {"az_rad", col_az},
                                     {"el_rad", col_el}}) {
        if (col < 0) {
          return Status::ParseError(where(line_no) + "header lacks column '" + name +
                                    "' (expected id,az_rad,el_rad)");
        }
      }
      if (beams_per_side == 0) {
        return Status::ParseError(where(line_no) +
                                  "missing '# beams_per_side: N' line before the header");
      }
      num_columns = fields.size();
      have_header = true;
      continue;
    }
    if (fields.size() != num_columns) {
      return Status::ParseError(where(line_no) + "expected " + std::to_string(num_columns) +
                                " fields as in the header, got " + std::to_string(fields.size()));
    }
    Beam b;
    if (!ParseInt(fields[col_id], &b.id)) {
      return Status::ParseError(where(line_no) + "field 'id': not an integer: " +
                                QuoteForMessage(fields[col_id], 40));
    }
    const int n2 = beams_per_side * beams_per_side;
    if (b.id < 1 || b.id > n2) {
      return Status::ParseError(where(line_no) + "field 'id': " + std::to_string(b.id) +
                                " is outside 1.." + std::to_string(n2));
    }
    if (!ParseDouble(fields[col_az], &b.az_rad)) {
      return Status::ParseError(where(line_no) + "field 'az_rad': not a finite number: " +
                                QuoteForMessage(fields[col_az], 40));
    }
    if (!ParseDouble(fields[col_el], &b.el_rad)) {
      return Status::ParseError(where(line_no) + "field 'el_rad': not a finite number: " +
                                QuoteForMessage(fields[col_el], 40));
    }
    if (std::abs(b.az_rad) > kPi) {
      return Status::ParseError(where(line_no) + "field 'az_rad': " +
                                SafeForMessage(fields[col_az], 40) +
                                " is outside [-pi, pi]");
    }
    if (std::abs(b.el_rad) >= 0.5 * kPi) {
      return Status::ParseError(where(line_no) + "field 'el_rad': " +
                                SafeForMessage(fields[col_el], 40) +
                                " is outside (-pi/2, pi/2)");
    }
    const auto [it, inserted] = line_of_id.emplace(b.id, line_no);
    if (!inserted) {
      return Status::ParseError(where(line_no) + "duplicate beam id " + std::to_string(b.id) +
                                " (first on line " + std::to_string(it->second) + ")");
    }
    beams.push_back(b);
  }
  if (in.bad()) return Status::IoError(path + ": read error");
  if (!have_header) {
    return Status::ParseError(path + ": no header line 'id,az_rad,el_rad'");
  }
  if (beams.empty()) return Status::ParseError(path + ": no beams");
  Result<BeamPattern> pattern = BeamPattern::Create(beams_per_side, std::move(beams));
  if (!pattern.ok()) return Status::ParseError(path + ": " + pattern.status().message());
  return pattern;
}

Status WritePatternCsv(const BeamPattern& pattern, const std::string& path) {
  std::ofstream out(path);
  if (!out) return Status::IoError(path + ": cannot open for writing");
  out << "# beams_per_side: " << pattern.beams_per_side() << "\n";
  out << "id,az_rad,el_rad\n";
  for (const Beam& b : pattern.beams()) {
    out << b.id << "," << FormatNumber(b.az_rad, 17) << "," << FormatNumber(b.el_rad, 17) << "\n";
  }
  out.flush();
  if (!out) return Status::IoError(path + ": write error");
  return Status::Ok();
}

}  // namespace opl
