// opl_camera: calibrates a camera from images of a board, and prints boards
// (docs/cli.md, docs/images.md "Calibrating a camera"). The work is done by
// opl::CalibrateCameraFromImageFiles (include/opl/pipeline/), the files by
// include/opl/io/ (board JSON, cameras JSON) and the pictures by
// include/opl/report/ (coverage, printable board); this file parses options,
// writes outputs atomically and maps errors to exit codes.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"
#include "opl/io/board_json.h"
#include "opl/io/cameras_json.h"
#include "opl/io/output_set.h"
#include "opl/pipeline/calibrate_camera_images.h"
#include "opl/report/board_print.h"
#include "opl/report/coverage_image.h"
#include "opl/report/plot_format.h"

namespace {

constexpr const char* kTool = "opl_camera";
constexpr const char* kReportJson = "camera_report.json";

struct Args {
  // calibrate
  std::vector<std::string> images;
  std::string board_path;
  std::string chessboard;  // "9x6"
  double square_mm = 0.0;
  std::string out_path;
  std::string into_path;
  std::string camera = "cam0";
  std::string report_dir;
  std::string coverage_format = "png";  // png, svg or pdf
  bool free_k3 = false;
  bool zero_tangential = false;
  bool fix_aspect_ratio = false;
  double max_view_rms_px = 0.0;
  int min_views = 3;
  // board
  std::string board_out;
  int rows = 0, cols = 0, first_id = 0;
  double tag_mm = 0.0, gap_mm = 0.0, margin_mm = 15.0, dpi = 300.0;
  std::string page = "fit";
  std::string board_json_out;
  int argc = 0;  // the command line, for the outputs' provenance
  char** argv = nullptr;
};

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// "9x6" -> 9, 6; false when malformed.
bool ParseColsRows(const std::string& text, int* cols, int* rows) {
  const size_t x = Lower(text).find('x');
  if (x == std::string::npos || x == 0 || x + 1 >= text.size()) return false;
  const std::string a = text.substr(0, x), b = text.substr(x + 1);
  auto digits = [](const std::string& s) {
    return !s.empty() && s.size() <= 4 && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
  };
  if (!digits(a) || !digits(b)) return false;
  *cols = std::stoi(a);
  *rows = std::stoi(b);
  return true;
}

std::string ReportFile(const Args& args, const std::string& name) {
  return args.report_dir.empty() ? std::string() : (std::filesystem::path(args.report_dir) / name).string();
}

// coverage.png, coverage.svg or coverage.pdf.
std::string CoverageName(const Args& args) { return "coverage." + args.coverage_format; }

int Calibrate(const Args& args) {
  using namespace opl;
  if (args.out_path.empty() && args.into_path.empty()) {
    return cli::Fail(kTool, "calibrate: give --out (a cameras JSON) and/or --into (a scene or cameras JSON)",
                     cli::kExitUsage);
  }
  if (args.camera.empty()) return cli::Fail(kTool, "--camera: must not be empty", cli::kExitUsage);
  Result<PlotFormat> format = PlotFormatFromPath(CoverageName(args));
  if (!format.ok()) return cli::Fail(kTool, "--coverage-format: " + format.status().message(), cli::kExitUsage);
  const PlotFormat coverage_format = *format;
  // The board.
  CalibrationBoard board;
  if (!args.board_path.empty()) {
    Result<CalibrationBoard> read = ReadBoardJson(args.board_path);
    if (!read.ok()) return cli::FailInput(kTool, read.status());
    board = *read;
  } else {
    Chessboard chess;
    if (!ParseColsRows(args.chessboard, &chess.inner_columns, &chess.inner_rows)) {
      return cli::Fail(kTool, "--chessboard: expected inner corners as COLSxROWS, e.g. 9x6, got '" + args.chessboard + "'",
                       cli::kExitUsage);
    }
    chess.square_size = args.square_mm;
    board = CalibrationBoard::ChessboardOf(chess);
    if (Status s = board.Validate(); !s.ok()) {
      return cli::Fail(kTool, "--chessboard/--square-mm: " + s.message(), cli::kExitUsage);
    }
  }
  // The images: one folder, or files.
  std::vector<std::string> files;
  std::error_code ec;
  if (args.images.size() == 1 && std::filesystem::is_directory(args.images[0], ec)) {
    Result<std::vector<std::string>> listed = ListImageFiles(args.images[0]);
    if (!listed.ok()) return cli::FailInput(kTool, listed.status());
    files = *listed;
  } else {
    files = args.images;
  }
  {
    std::vector<cli::NamedPath> inputs = {{"--board", args.board_path}};
    for (const std::string& f : files) inputs.push_back({"--images", f});
    if (std::optional<int> code = cli::RefuseOutputsOverInputs(
            kTool, inputs,
            {{"--out", args.out_path},
             {"--into", args.into_path},
             {"--report (" + std::string(kReportJson) + ")", ReportFile(args, kReportJson)},
             {"--report (" + CoverageName(args) + ")", ReportFile(args, CoverageName(args))}})) {
      return *code;
    }
  }
  // --into is read (and checked) before the long work.
  std::string into_text;
  if (!args.into_path.empty()) {
    Result<std::string> text = ReadFileToString(args.into_path);
    if (!text.ok()) return cli::FailInput(kTool, text.status());
    into_text = *text;
    if (Status s = CheckCamerasBlockDocument(into_text, args.into_path,
                                             std::filesystem::path(args.into_path).parent_path().string());
        !s.ok()) {
      return cli::FailInput(kTool, s);
    }
  }

  CameraImagesOptions options;
  options.calibration.fix_k3 = !args.free_k3;
  options.calibration.fix_tangential = args.zero_tangential;
  options.calibration.fix_aspect_ratio = args.fix_aspect_ratio;
  options.calibration.min_views = args.min_views;
  options.max_view_rms_px = args.max_view_rms_px;
  if (Status s = options.Validate(); !s.ok()) return cli::Fail(kTool, "invalid option: " + s.message(), cli::kExitUsage);
  Result<CameraImagesCalibration> cal = CalibrateCameraFromImageFiles(files, board, options);
  if (!cal.ok()) return cli::FailInput(kTool, cal.status());
  const SceneCamera camera = cal->ToSceneCamera(args.camera);

  // Every output or none, each with the run's provenance (io/output_set.h).
  std::vector<std::string> inputs = {args.board_path, args.into_path};
  inputs.insert(inputs.end(), files.begin(), files.end());
  Provenance provenance;
  if (std::optional<int> code = cli::MakeRunProvenance(kTool, args.argc, args.argv, inputs, &provenance)) {
    return *code;
  }

  // Everything is made before the first write.
  std::string out_text, into_updated, report_json, coverage_bytes;
  std::string into_note;
  if (!args.out_path.empty()) out_text = FormatCamerasJson({camera});
  if (!args.into_path.empty()) {
    Result<CamerasBlockUpdate> update = UpdateCamerasBlock(
        into_text, args.into_path, std::filesystem::path(args.into_path).parent_path().string(), camera);
    if (!update.ok()) return cli::FailInput(kTool, update.status());
    into_updated = update->text;
    into_note = std::string(update->replaced ? "  replaced" : "  added") + " camera '" + args.camera + "' in " +
                args.into_path + "\n";
  }
  if (!args.report_dir.empty()) {
    report_json = cal->ToJson();
    CoverageImageOptions copt;
    copt.title = "Camera '" + args.camera + "'";
    PlotMetadata metadata;  // a PDF's provenance (PNG and SVG are stamped when staged)
    metadata.creator = "OPL " + provenance.tool + " " + provenance.version;
    metadata.subject = FormatProvenanceJson(provenance);
    Result<std::vector<unsigned char>> picture = RenderCoverageImage(
        cal->width_px, cal->height_px, cal->views, cal->coverage, coverage_format, copt, metadata);
    if (!picture.ok()) return cli::Fail(kTool, picture.status().message(), cli::kExitInternalError);
    coverage_bytes.assign(picture->begin(), picture->end());
  }
  OutputSet outputs(provenance);
  if (!args.report_dir.empty()) {
    std::filesystem::create_directories(args.report_dir, ec);
    if (ec) {
      return cli::Fail(kTool, args.report_dir + ": cannot create the report folder: " + ec.message(),
                       cli::kExitWriteFailed);
    }
    if (Status s = outputs.Add(ReportFile(args, kReportJson), report_json); !s.ok()) return cli::FailWrite(kTool, s);
    // A PDF carries its provenance in its document information (set when drawn).
    const std::string coverage_path = ReportFile(args, CoverageName(args));
    if (Status s = coverage_format == PlotFormat::kPdf ? outputs.AddVerbatim(coverage_path, coverage_bytes)
                                                       : outputs.Add(coverage_path, coverage_bytes);
        !s.ok()) {
      return cli::FailWrite(kTool, s);
    }
  }
  if (!args.out_path.empty()) {
    if (Status s = outputs.Add(args.out_path, out_text); !s.ok()) return cli::FailWrite(kTool, s);
  }
  if (!args.into_path.empty()) {
    if (Status s = outputs.Add(args.into_path, into_updated); !s.ok()) return cli::FailWrite(kTool, s);
  }
  if (Status s = outputs.Commit(); !s.ok()) return cli::FailWrite(kTool, s);
  std::string text = cal->ToText() + into_note;
  if (!args.out_path.empty()) text += "  wrote camera '" + args.camera + "' to " + args.out_path + "\n";
  if (!args.report_dir.empty()) {
    text += "  report: " + ReportFile(args, kReportJson) + ", " + ReportFile(args, CoverageName(args)) + "\n";
  }
  return cli::PrintToStdout(kTool, text);
}

int Board(const Args& args) {
  using namespace opl;
  const std::string ext = Lower(std::filesystem::path(args.board_out).extension().string());
  if (ext != ".png" && ext != ".pdf") {
    return cli::Fail(kTool, "--out '" + args.board_out + "': the name must end in .png or .pdf", cli::kExitUsage);
  }
  if (std::optional<int> code =
          cli::RefuseOutputsOverInputs(kTool, {}, {{"--out", args.board_out}, {"--board-json", args.board_json_out}})) {
    return *code;
  }
  TagBoard board;
  board.columns = args.cols;
  board.rows = args.rows;
  board.tag_size = args.tag_mm;
  board.tag_gap = args.gap_mm;
  board.first_id = args.first_id;
  BoardPrintOptions options;
  options.margin_mm = args.margin_mm;
  options.dpi = args.dpi;
  options.page = args.page;
  if (Status s = board.Validate(); !s.ok()) return cli::Fail(kTool, "invalid board: " + s.message(), cli::kExitUsage);
  Result<BoardPrintLayout> layout = LayOutBoardPrint(board, options);
  if (!layout.ok()) return cli::Fail(kTool, "invalid board: " + layout.status().message(), cli::kExitUsage);
  Provenance provenance;
  if (std::optional<int> code = cli::MakeRunProvenance(kTool, args.argc, args.argv, {}, &provenance)) {
    return *code;
  }
  options.pdf_creator = "OPL " + provenance.tool + " " + provenance.version;
  options.pdf_subject = FormatProvenanceJson(provenance);
  Result<std::string> bytes = ext == ".pdf" ? RenderBoardPdf(board, options) : RenderBoardPng(board, options);
  if (!bytes.ok()) return cli::Fail(kTool, bytes.status().message(), cli::kExitInternalError);
  const std::string board_json = FormatBoardJson(CalibrationBoard::TagGrid(board));
  OutputSet outputs(provenance);
  // The PDF carries the provenance in its metadata (set above), the PNG and
  // the JSON in their own places.
  Status staged = ext == ".pdf" ? outputs.AddVerbatim(args.board_out, *bytes)
                                : outputs.Add(args.board_out, *bytes);
  if (!staged.ok()) return cli::FailWrite(kTool, staged);
  if (!args.board_json_out.empty()) {
    if (Status s = outputs.Add(args.board_json_out, board_json); !s.ok()) return cli::FailWrite(kTool, s);
  }
  if (Status s = outputs.Commit(); !s.ok()) return cli::FailWrite(kTool, s);
  std::string text = "board: " + CalibrationBoard::TagGrid(board).Describe() + "\n  page " +
                     FormatPrintf("%.2f", layout->page_width_mm) + " x " + FormatPrintf("%.2f", layout->page_height_mm) +
                     " mm";
  if (ext == ".png") {
    text += ", " + std::to_string(layout->png_width_px) + " x " + std::to_string(layout->png_height_px) + " px at " +
            FormatNumber(args.dpi) + " dpi";
  }
  text += "\n  wrote " + args.board_out + (args.board_json_out.empty() ? "" : " and " + args.board_json_out) +
          "\n  print at 100 % and check the 100 mm line with a ruler\n";
  return cli::PrintToStdout(kTool, text);
}

int Run(int argc, char** argv) {
  Args args;
  CLI::App app(
      "Calibrates a camera from photographs of a board, and prints boards (docs/images.md,\n"
      "'Calibrating a camera').\n"
      "\n"
      "  calibrate  finds the board in every image (an AprilTag grid described by a board\n"
      "             JSON, or a chessboard), calibrates the camera (pinhole + Brown-Conrady,\n"
      "             OpenCV's model) and writes its intrinsics with their standard deviations\n"
      "             as a cameras JSON (--out) or into the cameras block of a scene JSON\n"
      "             (--into); prints a report (per-view RMS, rejected images and why, how\n"
      "             much of the sensor the corners covered); --report DIR adds the report as\n"
      "             JSON and a coverage picture (PNG, SVG or PDF: --coverage-format).\n"
      "  board      writes a printable AprilTag grid board (PDF or PNG) at its exact size,\n"
      "             with a 100 mm scale check line and its parameters in the margin, and\n"
      "             the board JSON that calibrate reads.\n",
      kTool);
  app.require_subcommand(1);
  app.footer(opl::cli::HelpFooter(
      "  opl_camera board --out board.pdf --cols 6 --rows 4 --tag-mm 30 --gap-mm 7.5 \\\n"
      "      --board-json board.json\n"
      "  opl_camera calibrate --images shots/ --board board.json --out cameras.json --report rep/\n"
      "  opl_camera calibrate --images left*.jpg --chessboard 9x6 --square-mm 25 \\\n"
      "      --into scene.json --camera cam0\n"));

  CLI::App* calibrate = app.add_subcommand(
      "calibrate",
      "Calibrate a camera from images of a board. Output: the cameras JSON (--out, format\n"
      "opl.cameras) and/or the updated scene or cameras JSON (--into: the camera --camera is\n"
      "replaced, its pose kept, or added; every other field is kept), each written\n"
      "atomically, and a report on stdout. Images without the board are rejected and\n"
      "listed; at least --min-views must remain. The images must all have one size.");
  calibrate->add_option("--images", args.images,
                        "A folder (its .png .jpg .jpeg .tif .tiff .bmp .pgm .ppm files, by name)\n"
                        "or image files")
      ->required()
      ->type_name("DIR|FILE...");
  CLI::Option* board_opt = calibrate->add_option("--board", args.board_path,
                                                 "Board JSON (docs/formats.md 'Board JSON'; opl_camera board writes it)")
                               ->type_name("FILE");
  CLI::Option* chess_opt = calibrate->add_option("--chessboard", args.chessboard,
                                                 "A chessboard instead: its INNER corners, COLSxROWS (e.g. 9x6)")
                               ->type_name("COLSxROWS");
  CLI::Option* square_opt =
      calibrate->add_option("--square-mm", args.square_mm, "With --chessboard: the side of a square, mm")
          ->type_name("MM");
  board_opt->excludes(chess_opt);
  chess_opt->needs(square_opt);
  square_opt->needs(chess_opt);
  calibrate->add_option("--out", args.out_path, "Cameras JSON to write (a new file holding this camera)")
      ->type_name("FILE");
  calibrate->add_option("--into", args.into_path,
                        "Scene JSON or cameras JSON to update in place: its camera --camera")
      ->type_name("FILE");
  calibrate->add_option("--camera", args.camera, "Name of the camera written (default cam0)")->type_name("NAME");
  CLI::Option* report_opt =
      calibrate
          ->add_option("--report", args.report_dir,
                       "Folder (created if missing) for camera_report.json and coverage.png (or\n"
                       ".svg, .pdf: --coverage-format), the picture of where on the sensor the\n"
                       "corners fell; all files appear together or none")
          ->type_name("DIR");
  calibrate
      ->add_option("--coverage-format", args.coverage_format,
                   "With --report: the coverage picture as png (default), svg or pdf (vector,\n"
                   "for print); each carries the run's provenance (PNG text chunks, SVG\n"
                   "<metadata>, the PDF's document information)")
      ->check(CLI::IsMember({"png", "svg", "pdf"}))
      ->needs(report_opt)
      ->type_name("FORMAT");
  calibrate->add_flag("--free-k3", args.free_k3, "Estimate k3 too (default: k3 = 0; for wide-angle lenses)");
  calibrate->add_flag("--zero-tangential", args.zero_tangential, "Hold p1 = p2 = 0");
  calibrate->add_flag("--fix-aspect-ratio", args.fix_aspect_ratio, "Hold fx = fy (square pixels)");
  calibrate->add_option("--max-view-rms", args.max_view_rms_px,
                        "Reject views whose RMS reprojection error exceeds this, px, and calibrate\n"
                        "again without them (default 0: keep every view)")
      ->type_name("PX")
      ->check(CLI::Range(0.0, 1e6));
  calibrate->add_option("--min-views", args.min_views, "Fewest views with the board (default 3, >= 3)")
      ->type_name("N")
      ->check(CLI::Range(3, 100000));
  calibrate->footer(opl::cli::HelpFooter(
      "  opl_camera calibrate --images shots/ --board board.json --out cameras.json --report rep/\n"
      "  opl_camera calibrate --images shots/ --board board.json --out cameras.json --report rep/ \\\n"
      "      --coverage-format pdf\n"
      "  opl_camera calibrate --images /usr/share/doc/opencv-doc/examples/data/left0*.jpg \\\n"
      "      --chessboard 9x6 --square-mm 25 --out cameras.json\n"
      "  opl_camera calibrate --images shots/ --board board.json --into scene.json --camera cam2\n"));

  CLI::App* board = app.add_subcommand(
      "board",
      "Write a printable AprilTag (tag36h11) grid board at its exact physical size: PDF\n"
      "(vector) or PNG (--dpi, recorded in the file). The tags start --margin-mm from the\n"
      "top-left corner of the page; below them a 100 mm scale line (measure it on the\n"
      "print) and the board's parameters. --board-json writes the board JSON for\n"
      "calibrate. Print at 100 % (no 'fit to page') and glue it flat on a rigid plate.");
  board->add_option("--out", args.board_out, "board.pdf or board.png")->required()->type_name("FILE");
  board->add_option("--cols", args.cols, "Tags per row, 1..100")->required()->type_name("C");
  board->add_option("--rows", args.rows, "Tags per column, 1..100")->required()->type_name("R");
  board->add_option("--tag-mm", args.tag_mm, "Side of a tag's black square, mm")->required()->type_name("MM");
  board->add_option("--gap-mm", args.gap_mm, "White gap between neighbouring tags, mm (>= tag / 8)")
      ->required()
      ->type_name("MM");
  board->add_option("--first-id", args.first_id, "Id of the top-left tag; ids run row-major (default 0)")
      ->type_name("ID");
  board->add_option("--dpi", args.dpi, "PNG resolution, 50..2400 (default 300)")->type_name("N");
  board->add_option("--margin-mm", args.margin_mm, "White margin around the tags, mm (default 15)")
      ->type_name("MM");
  board->add_option("--page", args.page, "Page: fit (default), a4, a3 or letter")
      ->check(CLI::IsMember({"fit", "a4", "a3", "letter"}))
      ->type_name("SIZE");
  board->add_option("--board-json", args.board_json_out, "Board JSON to write beside it")->type_name("FILE");
  board->footer(opl::cli::HelpFooter(
      "  opl_camera board --out board.pdf --cols 6 --rows 4 --tag-mm 30 --gap-mm 7.5 \\\n"
      "      --page a4 --board-json board.json\n"
      "  opl_camera board --out board.png --cols 8 --rows 6 --tag-mm 20 --gap-mm 5 --dpi 600\n"));

  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  args.argc = argc;
  args.argv = argv;
  if (board->parsed()) return Board(args);
  if (args.board_path.empty() && args.chessboard.empty()) {
    return opl::cli::Fail(kTool, "calibrate: give --board FILE or --chessboard COLSxROWS --square-mm X",
                          opl::cli::kExitUsage);
  }
  return Calibrate(args);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
