#include "opl/io/board_json.h"

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "io/json_reader.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace {

using json = nlohmann::json;
using json_internal::JsonReader;

constexpr int kVersion = 1;

Status RequiredInteger(const JsonReader& r, const json& obj, const std::string& key, int* out) {
  const json* v = nullptr;
  OPL_RETURN_IF_ERROR(r.Require(obj, "", key, &v));
  return r.Integer(*v, key, out);
}

}  // namespace

Result<CalibrationBoard> ParseBoardJson(const std::string& text, const std::string& name) {
  const JsonReader r(name);
  Result<json> parsed = r.ParseText(text);
  if (!parsed.ok()) return parsed.status();
  const json& root = *parsed;
  if (!root.is_object()) return r.Error("", "expected a JSON object at the top level, got " + JsonReader::Describe(root));
  OPL_RETURN_IF_ERROR(r.CheckFormatAndVersion(root, "opl.board", kVersion));
  const json* v = nullptr;
  std::string type;
  OPL_RETURN_IF_ERROR(r.Require(root, "", "type", &v));
  OPL_RETURN_IF_ERROR(r.String(*v, "type", &type));
  CalibrationBoard board;
  if (type == "tag_grid") {
    OPL_RETURN_IF_ERROR(r.CheckKeys(root, "",
                                    {"format", "version", "description", "type", "family", "cols", "rows",
                                     "first_id", "tag_size_mm", "gap_mm", "pitch_mm", "provenance"}));
    if (const json* f = JsonReader::Find(root, "family")) {
      std::string family;
      OPL_RETURN_IF_ERROR(r.String(*f, "family", &family));
      if (family != "tag36h11") {
        return r.Error("family", "only \"tag36h11\" is supported, got " + JsonReader::Describe(*f));
      }
    }
    TagBoard& t = board.tag_grid;
    board.kind = CalibrationBoard::Kind::kTagGrid;
    OPL_RETURN_IF_ERROR(RequiredInteger(r, root, "cols", &t.columns));
    OPL_RETURN_IF_ERROR(RequiredInteger(r, root, "rows", &t.rows));
    OPL_RETURN_IF_ERROR(r.OptionalInteger(root, "", "first_id", &t.first_id));
    OPL_RETURN_IF_ERROR(r.RequiredNumber(root, "", "tag_size_mm", &t.tag_size));
    const json* gap = JsonReader::Find(root, "gap_mm");
    const json* pitch = JsonReader::Find(root, "pitch_mm");
    if ((gap == nullptr) == (pitch == nullptr)) {
      return r.Error(gap ? "pitch_mm" : "gap_mm", "give either \"gap_mm\" or \"pitch_mm\" (= tag_size_mm + gap_mm), not both nor neither");
    }
    if (gap != nullptr) {
      OPL_RETURN_IF_ERROR(r.Number(*gap, "gap_mm", &t.tag_gap));
    } else {
      double p = 0.0;
      OPL_RETURN_IF_ERROR(r.Number(*pitch, "pitch_mm", &p));
      if (!(p >= t.tag_size)) {
        return r.Error("pitch_mm", "must be >= tag_size_mm = " + FormatNumber(t.tag_size) + ", got " + FormatNumber(p));
      }
      t.tag_gap = p - t.tag_size;
    }
    if (t.columns < 1 || t.columns > 100) return r.Error("cols", "must be in [1, 100], got " + std::to_string(t.columns));
    if (t.rows < 1 || t.rows > 100) return r.Error("rows", "must be in [1, 100], got " + std::to_string(t.rows));
    if (!(t.tag_size > 0.0)) return r.Error("tag_size_mm", "must be > 0, got " + FormatNumber(t.tag_size));
    if (!(t.tag_gap >= 0.0)) return r.Error("gap_mm", "must be >= 0, got " + FormatNumber(t.tag_gap));
    if (t.first_id < 0 || t.first_id + t.columns * t.rows > 587) {
      return r.Error("first_id", "the ids first_id .. first_id + cols * rows - 1 = " + std::to_string(t.first_id) +
                                     " .. " + std::to_string(t.first_id + t.columns * t.rows - 1) +
                                     " must lie in [0, 586] (tag36h11)");
    }
  } else if (type == "chessboard") {
    OPL_RETURN_IF_ERROR(r.CheckKeys(root, "",
                                    {"format", "version", "description", "type", "inner_cols", "inner_rows",
                                     "square_mm", "provenance"}));
    board.kind = CalibrationBoard::Kind::kChessboard;
    Chessboard& c = board.chessboard;
    OPL_RETURN_IF_ERROR(RequiredInteger(r, root, "inner_cols", &c.inner_columns));
    OPL_RETURN_IF_ERROR(RequiredInteger(r, root, "inner_rows", &c.inner_rows));
    OPL_RETURN_IF_ERROR(r.RequiredNumber(root, "", "square_mm", &c.square_size));
    if (c.inner_columns < 2 || c.inner_columns > 200) {
      return r.Error("inner_cols", "must be in [2, 200], got " + std::to_string(c.inner_columns));
    }
    if (c.inner_rows < 2 || c.inner_rows > 200) {
      return r.Error("inner_rows", "must be in [2, 200], got " + std::to_string(c.inner_rows));
    }
    if (!(c.square_size > 0.0)) return r.Error("square_mm", "must be > 0, got " + FormatNumber(c.square_size));
  } else {
    return r.Error("type", "expected \"tag_grid\" or \"chessboard\", got " + JsonReader::Describe(*v));
  }
  if (const json* d = JsonReader::Find(root, "description")) {
    std::string ignored;
    OPL_RETURN_IF_ERROR(r.String(*d, "description", &ignored));
  }
  return board;
}

Result<CalibrationBoard> ReadBoardJson(const std::string& path) {
  Result<std::string> text = ReadFileToString(path, 1 << 20);
  if (!text.ok()) return text.status();
  return ParseBoardJson(*text, path);
}

std::string FormatBoardJson(const CalibrationBoard& board) {
  nlohmann::ordered_json root;
  root["format"] = "opl.board";
  root["version"] = kVersion;
  if (board.kind == CalibrationBoard::Kind::kChessboard) {
    root["type"] = "chessboard";
    root["inner_cols"] = board.chessboard.inner_columns;
    root["inner_rows"] = board.chessboard.inner_rows;
    root["square_mm"] = board.chessboard.square_size;
  } else {
    const TagBoard& t = board.tag_grid;
    root["type"] = "tag_grid";
    root["family"] = "tag36h11";
    root["cols"] = t.columns;
    root["rows"] = t.rows;
    root["first_id"] = t.first_id;
    root["tag_size_mm"] = t.tag_size;
    root["gap_mm"] = t.tag_gap;
  }
  return root.dump(2) + "\n";
}

}  // namespace opl
