// opl_simulate: simulated data of a module design (docs/cli.md).
//   opl_simulate spots --design D.json --out spots.csv [--seed S] [--missing F]
//                      [--outliers F] [--outlier-distance MM] [--noise-scale F]
//   opl_simulate slices --design D.json --out slices.csv [--depths LIST]
//                      [--tilt-deg A] [--curvature C] [the options of spots]
//   opl_simulate calibration --design D.json --out cal.json
//   opl_simulate mc --design D.json --iterations N [--seed S] [--threads T]
//                   [--noise-scale F] [--weighting W] [--json [--samples]]
//                   [--plot FIG.png]
//                   [--calibration [--depths LIST] [--tilt-deg A] [--curvature C]]
//   opl_simulate sweep --design D.json --param P --values LIST --out sweep.csv
//                   [--plot sweep.png] [--iterations N] [--seed S] [--threads T]
//                   [--weighting W]
//   opl_simulate images --scene S.json --out DIR [--shots LIST] [--threads T]
// The work is done by opl::SimulateSpots, opl::MakeCalibrationScreens,
// opl::SimulateSlices, opl::ExactCalibration (include/opl/sim/) and
// opl::RunMeasurementMonteCarlo, opl::MonteCarloFigure, opl::RunDesignSweep
// (include/opl/uncertainty/) and opl::RenderLinePlot (include/opl/report/)
// and opl::SceneRenderer
// (include/opl/lab/render_scene.h); this file
// parses options, reads the design, writes the output atomically and maps
// errors to exit codes.
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>


#include "cli_common.h"
#include "progress_bar.h"
#include "opl/core/format.h"
#include "opl/io/atomic_file.h"
#include "opl/io/module_calibration_json.h"
#include "opl/io/module_design_json.h"
#include "opl/io/output_set.h"
#include "opl/io/provenance_stamp.h"
#include "opl/io/scene_json.h"
#include "opl/lab/render_scene.h"
#include "opl/lab/shot_file.h"
#include "opl/io/spots_csv.h"
#include "opl/sim/module_design.h"
#include "opl/sim/simulate_slices.h"
#include "opl/sim/simulate_spots.h"
#include "opl/report/line_plot.h"
#include "opl/report/plot_format.h"
#include "opl/uncertainty/calibration_monte_carlo.h"
#include "opl/uncertainty/design_sweep.h"
#include "opl/uncertainty/monte_carlo.h"
#include "opl/uncertainty/monte_carlo_figure.h"

namespace {

constexpr const char* kTool = "opl_simulate";

struct Args {
  std::string design_path;
  std::string out_path;
  opl::SpotSimulationOptions spots;
  double noise_scale = 1.0;
  // slices only
  bool depths_given = false;  // false: the design's own planes are the slices
  std::string depths;
  double tilt_deg = 0.0;
  double curvature_per_mm = 0.0;
  // mc only
  int iterations = 0;
  int threads = 0;
  bool json = false;
  std::string weighting = "efficient";
  bool calibration = false;  // mc of a calibration session
  bool samples = false;      // mc --json: every iteration's values too
  // mc and sweep
  std::string plot_path;
  // sweep only
  std::string param;
  std::string values;
  bool log_x = false;
  bool log_y = false;
  // images only
  std::string scene_path;
  std::string shots;
  // Written into every output (io/provenance_stamp.h).
  opl::Provenance provenance;
};

// `contents` written to `path` atomically with the run's provenance.
opl::Status WriteStamped(const Args& args, const std::string& path, const std::string& contents) {
  opl::Result<std::string> stamped = opl::StampProvenance(path, contents, args.provenance);
  if (!stamped.ok()) return stamped.status();
  return opl::WriteFileAtomically(path, *stamped);
}

// What `spots` and `slices` share before simulating: checks --noise-scale,
// reads the design, scales its noise and validates the spot options. Returns
// the exit code when the command must stop.
std::optional<int> PrepareSpotSimulation(const Args& args, opl::ModuleDesign* design,
                                         opl::SpotSimulationOptions* options) {
  using namespace opl;
  if (!(std::isfinite(args.noise_scale) && args.noise_scale >= 0.0)) {
    return cli::Fail(kTool, "--noise-scale must be finite and >= 0, got " +
                                std::to_string(args.noise_scale),
                     cli::kExitBadInput);
  }
  Result<ModuleDesign> read = ReadModuleDesignJson(args.design_path);
  if (!read.ok()) return cli::FailInput(kTool, read.status());
  *design = std::move(*read);
  design->spot_noise_mm *= args.noise_scale;

  // A spots CSV carries per-coordinate standard deviations, which must be > 0:
  // attach them only when the noise has a positive variance on every axis.
  *options = args.spots;
  const Eigen::Vector3d variance = design->SpotCovarianceMm2().diagonal();
  options->attach_covariance = (variance.array() > 0.0).all();
  if (Status st = options->Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }
  return std::nullopt;
}

// Writes simulated spots as a spots CSV (atomically): the standard columns,
// then the simulation's ground truth (ignored by readers).
// With `screens` (a calibration session of that many screens), the slice
// column numbers the grid photographs, as opl_calibrate reads them (one
// source per slice): source i (design order) on screen k is slice i * screens
// + k, and a `screen` column gives k.
int WriteSimulatedSpots(const Args& args, const std::vector<opl::SimulatedSpot>& simulated,
                        const opl::ModuleDesign& design, const std::string& path,
                        int screens = 0) {
  using namespace opl;
  SpotsCsvExtraColumn slice{"slice", {}}, screen{"screen", {}}, outlier{"outlier", {}};
  SpotsCsvExtraColumn true_xyz[3] = {{"true_x", {}}, {"true_y", {}}, {"true_z", {}}};
  for (const SimulatedSpot& s : simulated) {
    int source_index = 0;
    while (design.sources[source_index].name != s.spot.source) ++source_index;
    slice.values.push_back(std::to_string(screens > 0 ? source_index * screens + s.slice : s.slice));
    screen.values.push_back(std::to_string(s.slice));
    outlier.values.push_back(s.outlier ? "1" : "0");
    for (int k = 0; k < 3; ++k) {
      char buffer[32];
      std::snprintf(buffer, sizeof(buffer), "%.17g", s.true_point_in_scene[k]);
      true_xyz[k].values.push_back(buffer);
    }
  }
  std::vector<SpotsCsvExtraColumn> extra = {slice};
  if (screens > 0) extra.push_back(screen);
  for (const SpotsCsvExtraColumn& c : {outlier, true_xyz[0], true_xyz[1], true_xyz[2]}) {
    extra.push_back(c);
  }
  Result<std::string> csv = FormatSpotsCsv(SpotsOf(simulated), extra);
  if (!csv.ok()) return cli::FailInput(kTool, csv.status());
  if (Status st = WriteStamped(args, path, *csv); !st.ok()) return cli::FailWrite(kTool, st);
  return cli::kExitOk;
}

int SimulateSpotsCommand(const Args& args) {
  using namespace opl;
  ModuleDesign design;
  SpotSimulationOptions options;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &options)) return *code;
  Result<std::vector<SimulatedSpot>> simulated = SimulateSpots(design, options);
  if (!simulated.ok()) return cli::FailInput(kTool, simulated.status());
  return WriteSimulatedSpots(args, *simulated, design, args.out_path);
}

int SimulateSlicesCommand(const Args& args) {
  using namespace opl;
  // The syntax of --depths is part of the command line: a usage error.
  ScreenSlicesOptions screen_options;
  if (args.depths_given) {
    Result<std::vector<double>> depths = ParseDepthList(args.depths);
    if (!depths.ok()) {
      return cli::Fail(kTool, "--depths: " + depths.status().message() + " (see --help)",
                       cli::kExitUsage);
    }
    screen_options.depths_mm = std::move(*depths);
  }
  screen_options.tilt_deg = args.tilt_deg;
  screen_options.curvature_per_mm = args.curvature_per_mm;

  ModuleDesign design;
  SpotSimulationOptions options;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &options)) return *code;

  std::vector<Surface> screens;
  if (!args.depths_given) {
    if (design.surface.type() != SurfaceType::kPlanes) {
      return cli::Fail(kTool,
                       "--depths is required: the design's surface is a " +
                           std::string(design.surface.TypeName()) +
                           ", not a list of planes (see --help)",
                       cli::kExitUsage);
    }
    screens = SlicesOf(design.surface);
  } else {
    if (Status st = screen_options.Validate(); !st.ok()) {
      return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
    }
    Result<std::vector<Surface>> made = MakeCalibrationScreens(design, screen_options);
    if (!made.ok()) return cli::FailInput(kTool, made.status());
    screens = std::move(*made);
  }
  Result<std::vector<SimulatedSpot>> simulated = SimulateSlices(design, screens, options);
  if (!simulated.ok()) return cli::FailInput(kTool, simulated.status());
  return WriteSimulatedSpots(args, *simulated, design, args.out_path,
                             static_cast<int>(screens.size()));
}

int CalibrationCommand(const Args& args) {
  using namespace opl;
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  Result<ModuleCalibration> calibration = ExactCalibration(*design);
  if (!calibration.ok()) return cli::FailInput(kTool, calibration.status());
  Result<std::string> json = FormatModuleCalibrationJson(*calibration);
  if (!json.ok()) return cli::FailInput(kTool, json.status());
  if (Status st = WriteStamped(args, args.out_path, *json); !st.ok()) {
    return cli::FailWrite(kTool, st);
  }
  return cli::kExitOk;
}

// Runs a Monte Carlo (`run` on `options`) with a progress bar on a terminal
// and warns on stderr about failed iterations. Returns the exit code when the
// run failed.
template <class Options, class Run, class Report>
std::optional<int> RunWithProgress(Options options, const Run& run, Report* report) {
  using namespace opl;
  cli::ProgressBar bar("mc", cli::StderrIsTerminal());
  options.progress = [&bar](int done, int total) { bar.Update(done, total); };
  auto result = run(options);
  bar.Finish();
  if (!result.ok()) return cli::FailInput(kTool, result.status());
  *report = std::move(*result);
  if (report->failed > 0) {
    std::fprintf(stderr, "%s: warning: %d of %d iterations failed and were left out; %s\n",
                 kTool, report->failed, report->iterations, report->first_failure.c_str());
  }
  return std::nullopt;
}

// --plot names a .png, .svg or .pdf (report/plot_format.h), checked before
// any work.
std::optional<int> CheckPlotPath(const std::string& path) {
  if (path.empty()) return std::nullopt;
  opl::Result<opl::PlotFormat> format = opl::PlotFormatFromPath(path);
  if (!format.ok()) return opl::cli::Fail(kTool, "--plot " + format.status().message(), opl::cli::kExitUsage);
  return std::nullopt;
}

// Renders `plot` in the format its path names and stages it in `outputs`
// with the run's provenance (PNG text chunks and SVG metadata are stamped by
// OutputSet::Add; a PDF carries it in its document metadata). A non-OK
// result is a failure to render (kExitInternalError) or to stage (a write
// error), told apart by *render_failed.
opl::Status StagePlot(const opl::LinePlot& plot, const std::string& path, const opl::Provenance& provenance,
                      opl::OutputSet* outputs, bool* render_failed) {
  *render_failed = false;
  opl::Result<opl::PlotFormat> format = opl::PlotFormatFromPath(path);
  if (!format.ok()) return format.status();
  opl::PlotMetadata metadata;
  metadata.creator = "OPL " + provenance.tool + " " + provenance.version;
  metadata.subject = opl::FormatProvenanceJson(provenance);
  opl::Result<std::vector<unsigned char>> bytes = opl::RenderLinePlot(plot, *format, metadata);
  if (!bytes.ok()) {
    *render_failed = true;
    return bytes.status();
  }
  const std::string data(bytes->begin(), bytes->end());
  return *format == opl::PlotFormat::kPdf ? outputs->AddVerbatim(path, data) : outputs->Add(path, data);
}

int CalibrationMonteCarloCommand(const Args& args, const opl::ModuleDesign& design) {
  using namespace opl;
  CalibrationMonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  if (args.depths_given) {
    Result<std::vector<double>> depths = ParseDepthList(args.depths);
    if (!depths.ok()) {
      return cli::Fail(kTool, "--depths: " + depths.status().message() + " (see --help)",
                       cli::kExitUsage);
    }
    options.screens.depths_mm = std::move(*depths);
  }
  options.screens.tilt_deg = args.tilt_deg;
  options.screens.curvature_per_mm = args.curvature_per_mm;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: " + st.message(), cli::kExitBadInput);
  }
  CalibrationMonteCarloReport report;
  if (std::optional<int> code = RunWithProgress(
          options,
          [&design](const CalibrationMonteCarloOptions& o) {
            return RunCalibrationMonteCarlo(design, o);
          },
          &report)) {
    return *code;
  }
  return args.json ? cli::PrintJsonToStdout(kTool, report.ToJson(), args.provenance)
                   : cli::PrintToStdout(kTool, report.ToText());
}

int MonteCarloCommand(const Args& args) {
  using namespace opl;
  if (std::optional<int> code = CheckPlotPath(args.plot_path)) return *code;
  ModuleDesign design;
  SpotSimulationOptions unused;
  if (std::optional<int> code = PrepareSpotSimulation(args, &design, &unused)) return *code;
  if (args.calibration) {
    if (args.weighting != "efficient") {
      return cli::Fail(kTool, "--weighting applies to a measurement, not to --calibration",
                       cli::kExitUsage);
    }
    if (!args.plot_path.empty() || args.samples) {
      return cli::Fail(kTool, "--plot and --samples apply to a measurement, not to --calibration",
                       cli::kExitUsage);
    }
    return CalibrationMonteCarloCommand(args, design);
  }
  if (args.depths_given || args.tilt_deg != 0.0 || args.curvature_per_mm != 0.0) {
    return cli::Fail(kTool, "--depths, --tilt-deg and --curvature need --calibration",
                     cli::kExitUsage);
  }
  MonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  Result<SpotWeighting> weighting = ParseSpotWeighting(args.weighting);
  if (!weighting.ok()) {
    return cli::Fail(kTool, "--weighting: " + weighting.status().message(), cli::kExitUsage);
  }
  options.weighting = *weighting;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: --" + st.message(), cli::kExitBadInput);
  }
  MonteCarloReport report;
  if (std::optional<int> code = RunWithProgress(
          options,
          [&design](const MonteCarloOptions& o) { return RunMeasurementMonteCarlo(design, o); },
          &report)) {
    return *code;
  }
  // The figure is the run's one file: rendered, then written atomically
  // (io/output_set.h), before anything is printed; on any error nothing is
  // written and nothing printed.
  if (!args.plot_path.empty()) {
    OutputSet outputs(args.provenance);
    bool render_failed = false;
    if (Status st = StagePlot(MonteCarloFigure(report), args.plot_path, args.provenance, &outputs, &render_failed);
        !st.ok()) {
      return render_failed ? cli::Fail(kTool, "plot: " + st.message(), cli::kExitInternalError)
                           : cli::FailWrite(kTool, st);
    }
    if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);
  }
  return args.json ? cli::PrintJsonToStdout(kTool, report.ToJson(args.samples), args.provenance)
                   : cli::PrintToStdout(kTool, report.ToText());
}

int SweepCommand(const Args& args) {
  using namespace opl;
  if (std::optional<int> code = CheckPlotPath(args.plot_path)) return *code;
  Result<SweepParameter> parameter = ParseSweepParameter(args.param);
  if (!parameter.ok()) return cli::Fail(kTool, "--param: " + parameter.status().message(), cli::kExitUsage);
  if (args.log_x && IsCategoricalSweep(*parameter)) {
    return cli::Fail(kTool, "--log-x: --param " + args.param + " has named values, not a numeric axis",
                     cli::kExitUsage);
  }
  Result<std::vector<double>> values = ParseSweepValues(args.param, args.values);
  if (!values.ok()) return cli::Fail(kTool, "--values: " + values.status().message(), cli::kExitUsage);
  Result<SpotWeighting> weighting = ParseSpotWeighting(args.weighting);
  if (!weighting.ok()) {
    return cli::Fail(kTool, "--weighting: " + weighting.status().message(), cli::kExitUsage);
  }
  Result<ModuleDesign> design = ReadModuleDesignJson(args.design_path);
  if (!design.ok()) return cli::FailInput(kTool, design.status());
  MonteCarloOptions options;
  options.iterations = args.iterations;
  options.seed = args.spots.seed;
  options.threads = args.threads;
  options.weighting = *weighting;
  if (Status st = options.Validate(); !st.ok()) {
    return cli::Fail(kTool, "invalid option: --" + st.message(), cli::kExitBadInput);
  }
  // Every value is checked before the first Monte Carlo runs.
  for (double value : *values) {
    Result<ModuleDesign> changed = ApplySweepValue(*design, *parameter, value);
    if (!changed.ok()) return cli::FailInput(kTool, changed.status());
  }
  cli::ProgressBar bar("sweep", cli::StderrIsTerminal());
  options.progress = [&bar](int done, int total) { bar.Update(done, total); };
  Result<DesignSweep> sweep = RunDesignSweep(*design, *parameter, *values, options);
  bar.Finish();
  if (!sweep.ok()) return cli::FailInput(kTool, sweep.status());

  // Both outputs are made before either is written.
  const std::string csv = sweep->ToCsv();
  // Both or neither (io/output_set.h).
  OutputSet outputs(args.provenance);
  if (Status st = outputs.Add(args.out_path, csv); !st.ok()) return cli::FailWrite(kTool, st);
  if (!args.plot_path.empty()) {
    LinePlot plot = sweep->ToPlot();
    for (PlotPanel& panel : plot.panels) {
      panel.log_x = args.log_x;
      panel.log_y = args.log_y;
    }
    bool render_failed = false;
    if (Status st = StagePlot(plot, args.plot_path, args.provenance, &outputs, &render_failed); !st.ok()) {
      return render_failed ? cli::Fail(kTool, "plot: " + st.message(), cli::kExitInternalError)
                           : cli::FailWrite(kTool, st);
    }
  }
  if (Status st = outputs.Commit(); !st.ok()) return cli::FailWrite(kTool, st);

  char line[256];
  std::snprintf(line, sizeof(line), "%-16s %-7s %12s %12s %12s %7s %13s %6s\n",
                SweepParameterName(*parameter), "L", "std MC (mm)", "FO (mm)", "CRB (mm)",
                "MC/CRB", "u(L)/L (ppm)", "failed");
  std::string table = line;
  for (const DesignSweepPoint& p : sweep->points) {
    for (const MonteCarloLength& l : p.report.lengths) {
      const SampleSummary& s = l.photo_mm;
      std::snprintf(line, sizeof(line), "%-16s %-7s %12.5f %12.5f %12.5f %7.3f %13.0f %6d\n",
                    SweepValueText(*parameter, p.value).c_str(), (l.from + "-" + l.to).c_str(), s.std_dev, s.first_order_std,
                    s.cramer_rao_std, s.cramer_rao_std > 0 ? s.std_dev / s.cramer_rao_std : 0.0,
                    1e6 * s.std_dev / l.true_mm, p.report.failed);
      table += line;
    }
  }
  return cli::PrintToStdout(kTool, table);
}

// The shot indices of --shots ("0,3,5"; empty: every shot), or an error
// message.
std::optional<std::string> ParseShotList(const std::string& text, int num_shots,
                                         std::vector<int>* indices) {
  indices->clear();
  if (text.empty()) {
    for (int k = 0; k < num_shots; ++k) indices->push_back(k);
    return std::nullopt;
  }
  std::set<int> seen;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    size_t used = 0;
    int index = -1;
    try {
      index = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || index < 0) {
      return "--shots: '" + item + "' is not a shot index (expected e.g. 0,3,5)";
    }
    if (index >= num_shots) {
      return "--shots: " + item + ": the scene has " + std::to_string(num_shots) +
             " shots, 0.." + std::to_string(num_shots - 1);
    }
    if (seen.insert(index).second) indices->push_back(index);
    start = comma + 1;
  }
  return std::nullopt;
}

int ImagesCommand(const Args& args) {
  using namespace opl;
  namespace fs = std::filesystem;
  Result<Scene> scene = ReadSceneJson(args.scene_path);
  if (!scene.ok()) return cli::FailInput(kTool, scene.status());
  std::vector<int> indices;
  if (std::optional<std::string> bad =
          ParseShotList(args.shots, static_cast<int>(scene->shots.size()), &indices)) {
    return cli::Fail(kTool, *bad + " (see --help)", cli::kExitUsage);
  }
  if (args.threads < 0) return cli::Fail(kTool, "--threads must be >= 0", cli::kExitUsage);
  for (size_t k = 0; k < scene->shots.size(); ++k) {
    const fs::path file(scene->shots[k].file);
    bool escapes = file.is_absolute();
    for (const fs::path& part : file) escapes = escapes || part == "..";
    if (escapes || file.filename().empty()) {
      return cli::Fail(kTool,
                       args.scene_path + ": shots[" + std::to_string(k) + "].file: '" +
                           scene->shots[k].file +
                           "': must be a relative file path inside the output folder",
                       cli::kExitBadInput);
    }
  }
  Result<SceneRenderer> renderer = SceneRenderer::Create(*scene);
  if (!renderer.ok()) return cli::FailInput(kTool, Status(renderer.status().code(),
                                                          args.scene_path + ": " +
                                                              renderer.status().message()));

  // Output folders (created when missing).
  const fs::path out_dir(args.out_path);
  std::error_code ec;
  std::set<fs::path> folders = {out_dir};
  for (int k : indices) {
    folders.insert((out_dir / scene->shots[static_cast<size_t>(k)].file).parent_path());
  }
  // The folders this run creates, removed again (when empty) on failure.
  std::set<fs::path> created;
  for (const fs::path& folder : folders) {
    for (fs::path p = folder; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      created.insert(p);
    }
  }
  auto remove_created = [&created, &ec]() {
    for (auto it = created.rbegin(); it != created.rend(); ++it) fs::remove(*it, ec);
  };
  for (const fs::path& folder : folders) {
    fs::create_directories(folder, ec);
    if (ec || !fs::is_directory(folder)) {
      remove_created();
      return cli::Fail(kTool, folder.string() + ": cannot create the output folder: " +
                                  (ec ? ec.message() : std::string("not a directory")),
                       cli::kExitWriteFailed);
    }
  }

  // Render, encode and write the shots, `threads` at a time.
  const int total = static_cast<int>(indices.size());
  unsigned threads = args.threads > 0 ? static_cast<unsigned>(args.threads)
                                      : std::max(1u, std::thread::hardware_concurrency());
  threads = std::min(threads, static_cast<unsigned>(std::max(1, total)));
  std::vector<RenderedShot> rendered(indices.size());
  std::vector<std::string> written;
  std::atomic<int> next{0};
  std::mutex mutex;
  Status failure;
  bool write_failure = false;
  int done = 0;
  cli::ProgressBar bar("images", cli::StderrIsTerminal());
  bar.Update(0, total);
  auto work = [&]() {
    for (;;) {
      const int slot = next.fetch_add(1);
      if (slot >= total) return;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (!failure.ok()) return;
      }
      const int index = indices[static_cast<size_t>(slot)];
      const SceneShot& shot = scene->shots[static_cast<size_t>(index)];
      const std::string path = (out_dir / shot.file).string();
      Result<RenderedShot> r = renderer->RenderShot(index);
      Status st = r.ok() ? Status::Ok()
                         : Status(r.status().code(), "shots[" + std::to_string(index) +
                                                         "]: " + r.status().message());
      bool is_write = false;
      if (st.ok()) {
        Result<std::string> file = EncodeShotImage(r->image, scene->image);
        r->image.release();
        if (!file.ok()) {
          st = Status::IoError(path + ": " + file.status().message());
          is_write = true;
        } else {
          st = WriteStamped(args, path, *file);
          is_write = !st.ok();
        }
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (!st.ok()) {
        if (failure.ok()) {
          failure = st;
          write_failure = is_write;
        }
        return;
      }
      written.push_back(path);
      rendered[static_cast<size_t>(slot)] = std::move(*r);
      bar.Update(++done, total);
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  bar.Finish();

  const std::string truth_path = (out_dir / "truth.json").string();
  if (failure.ok()) {
    failure = WriteStamped(args, truth_path, FormatSceneTruthJson(*renderer, rendered));
    write_failure = !failure.ok();
  }
  if (!failure.ok()) {
    // No partial output: remove the images this run wrote.
    for (const std::string& path : written) fs::remove(path, ec);
    remove_created();
    return write_failure ? cli::FailWrite(kTool, failure) : cli::FailInput(kTool, failure);
  }

  std::string summary;
  for (const RenderedShot& r : rendered) {
    const SceneShot& shot = scene->shots[static_cast<size_t>(r.shot_index)];
    int tags_in = 0, spots_in = 0;
    for (const TagView& t : r.tags) tags_in += t.in_image ? 1 : 0;
    for (const SpotView& s : r.spots) spots_in += s.visible ? 1 : 0;
    char line[512];
    std::snprintf(line, sizeof(line),
                  "%s  camera %s  lasers %d  tags in image %d/%zu  spots visible %d/%zu\n",
                  (out_dir / shot.file).string().c_str(), shot.camera.c_str(),
                  static_cast<int>(shot.lasers.size()), tags_in, r.tags.size(), spots_in,
                  r.spots.size());
    summary += line;
  }
  summary += truth_path + "\n";
  return cli::PrintToStdout(kTool, summary);
}

void AddDesignAndOut(CLI::App* command, Args* args, const std::string& out_help) {
  command
      ->add_option("--design", args->design_path,
                   "Module design JSON (docs/simulation.md, 'Module design JSON')")
      ->required()
      ->type_name("FILE");
  command->add_option("--out", args->out_path, out_help)->required()->type_name("FILE");
}

// The options of the random spot simulation (SpotSimulationOptions and the
// noise scale), shared by `spots` and `slices`.
void AddSpotOptions(CLI::App* command, Args* args) {
  command
      ->add_option("--seed", args->spots.seed,
                   "Seed of every random choice, 0 to 2^64 - 1; the same seed gives the same\n"
                   "spots")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  command
      ->add_option("--missing", args->spots.missing_fraction,
                   "Fraction of the spots dropped, in [0, 1]")
      ->capture_default_str();
  command
      ->add_option("--outliers", args->spots.outlier_fraction,
                   "Fraction of the kept spots made outliers, in [0, 1]")
      ->capture_default_str();
  command
      ->add_option("--outlier-distance", args->spots.outlier_distance_mm,
                   "Displacement of an outlier across its beam, mm, > 0")
      ->capture_default_str();
  command
      ->add_option("--noise-scale", args->noise_scale,
                   "Multiplies the design's spot noise (spot_noise_mm); 0 gives noise-free\n"
                   "spots (written without sx,sy,sz), >= 0")
      ->capture_default_str();
}

int Run(int argc, char** argv) {
  Args args;
  CLI::App app(
      "Simulates the data of an optically projected length scale module from its design\n"
      "(sources, patterns, poses, surface, spot noise): the spots its grids throw on the\n"
      "design's surface, the spots of a calibration session (a screen at several depths),\n"
      "or the exact calibration of the design. A simulated calibration and simulated\n"
      "spots are what opl_measure reads, so the two tools together test a design end to\n"
      "end (with zero noise, opl_measure finds s = 1). `mc` runs the Monte Carlo\n"
      "uncertainty of a measurement (JCGM 101) of the design, `sweep` a design study.\n"
      "`images` renders the camera images of a whole scene (tags and laser spots) with\n"
      "their ground truth, for the image front end.\n",
      kTool);
  app.require_subcommand(1);
  const std::string examples =
      "  opl_simulate calibration --design examples/prototype_design.json --out cal.json\n"
      "  opl_simulate spots --design examples/prototype_design.json --out spots.csv --seed 7 \\\n"
      "      --missing 0.1 --outliers 0.02\n"
      "  opl_simulate spots --design examples/prototype_design.json --out exact.csv --noise-scale 0\n"
      "  opl_measure --calibration cal.json --spots spots.csv\n"
      "  opl_simulate slices --design examples/prototype_design.json --depths 750:65:1335 \\\n"
      "      --out slices.csv --tilt-deg 3 --curvature 2e-5 --missing 0.05 --outliers 0.01\n";
  app.footer(opl::cli::HelpFooter(examples));

  CLI::App* spots = app.add_subcommand(
      "spots",
      "Write the simulated spots of every source as a spots CSV: source,beam,x,y,z\n"
      "(mm, the design's scene frame), sx,sy,sz (the noise standard deviations, when\n"
      "> 0 on every axis), then ground truth columns slice,outlier,true_x,true_y,true_z.");
  AddDesignAndOut(spots, &args, "Spots CSV to write (atomically)");
  AddSpotOptions(spots, &args);
  spots->footer(opl::cli::HelpFooter(examples));

  CLI::App* slices = app.add_subcommand(
      "slices",
      "Simulate a calibration session (docs/simulation.md, 'Simulating a calibration\n"
      "session'): the module stays fixed and a screen is placed at several depths; every\n"
      "grid throws its spots on every screen, one grid photographed at a time. Written as\n"
      "the spots CSV of `spots`, ready for opl_calibrate: a slice is one grid on one\n"
      "screen, so source i (design order) on screen k is slice i * K + k (K screens),\n"
      "and a `screen` column after `slice` gives k. Missing spots, outliers and noise are\n"
      "drawn for each screen on its own (seed derived from --seed and k), so --missing\n"
      "0.1 drops 10% of the spots of every screen.\n"
      "\n"
      "Depths (--depths) are in mm, in the design's scene frame, measured from the mean\n"
      "projection origin of the sources along the module's mean viewing direction (the\n"
      "mean of the sources' central beams). For examples/prototype_design.json (sources\n"
      "at y = +-27.5 mm looking along +X) a depth is the scene x of the screen.\n"
      "  --depths 750:65:1335     first:step:last, last included: 750, 815, ..., 1335\n"
      "  --depths 750,815,1000    a comma-separated list\n"
      "Without --depths the design's surface must be a list of planes (\"planes\"):\n"
      "each plane is a slice. --tilt-deg turns screen k about the module's up axis by\n"
      "+A (even k) or -A (odd k) degrees, so neighbouring screens are not parallel;\n"
      "--curvature makes every screen a paraboloid z' = C/2 r'^2 (C > 0: the edges bend\n"
      "towards the module). Either way the point at each depth on the viewing axis stays\n"
      "on its screen.");
  AddDesignAndOut(slices, &args, "Spots CSV to write (atomically), with the slice column");
  CLI::Option* depths =
      slices
          ->add_option("--depths", args.depths,
                       "Screen depths, mm: first:step:last or a comma-separated list; required\n"
                       "unless the design's surface is a list of planes")
          ->type_name("LIST");
  slices
      ->add_option("--tilt-deg", args.tilt_deg,
                   "Tilt of the screens about the module's up axis, degrees, |A| < 90,\n"
                   "alternating sign (+A, -A, +A, ...)")
      ->needs(depths)
      ->capture_default_str();
  slices
      ->add_option("--curvature", args.curvature_per_mm,
                   "Curvature of every screen, 1/mm (0: flat); > 0 bends the edges towards\n"
                   "the module")
      ->needs(depths)
      ->capture_default_str();
  AddSpotOptions(slices, &args);
  slices->footer(opl::cli::HelpFooter(examples));

  CLI::App* calibration = app.add_subcommand(
      "calibration",
      "Write the exact (noise-free) module calibration of the design: its patterns, its\n"
      "source poses (the calibration frame is the design's scene frame) and the\n"
      "separations between every pair of origins, with zero uncertainty.");
  AddDesignAndOut(calibration, &args, "Module calibration JSON to write (atomically)");
  calibration->footer(opl::cli::HelpFooter(examples));

  CLI::App* mc = app.add_subcommand(
      "mc",
      "Monte Carlo uncertainty of a measurement (JCGM 101, GUM Supplement 1;\n"
      "docs/uncertainty.md). The design's surface is the scene and its exact calibration\n"
      "the calibration (so s = 1 on average). Every iteration adds the design's spot noise\n"
      "(spot_noise_mm, times --noise-scale) to the noise-free spots of every source,\n"
      "locates every source and computes every length L between origins (mm, the design's\n"
      "frame) and the scale factor s, as opl_measure would. Printed on stdout:\n"
      "  - per length: mean, standard deviation and 95 % coverage interval of L;\n"
      "  - s: mean, standard deviation (ppm), 95 % coverage interval;\n"
      "  - per source: mean and standard deviation of the origin (x, y, z) and of the\n"
      "    pose angles (R = Rx Ry Rz);\n"
      "each next to the first-order prediction (the covariance the locate and scale\n"
      "solves report for the noise-free spots carrying the design's noise) and the\n"
      "Cramer-Rao bound (the least covariance any unbiased estimator can reach for that\n"
      "noise, docs/uncertainty.md), with the ratios MC/FO and MC/CRB. Coverage\n"
      "intervals are the probabilistically symmetric ones of JCGM 101 7.7.1 (the\n"
      "shortest, 7.7.2, is also in the JSON). Use at least a few thousand iterations\n"
      "for a stable 95 % interval. --plot draws the histograms of L and s against the\n"
      "first-order normal density with both 95 % intervals (the one to look at: is the\n"
      "output normal, unbiased, as wide as predicted?); --json --samples adds every\n"
      "iteration's values to the JSON.\n"
      "\n"
      "The run uses --threads cores (default: all); the result depends only on the design,\n"
      "--iterations and --seed, never on the thread count. A progress bar is drawn on\n"
      "stderr when stderr is a terminal. Iterations whose locate fails are counted and\n"
      "reported, not fatal, unless all fail (exit 4).");
  mc->add_option("--design", args.design_path,
                 "Module design JSON (docs/simulation.md, 'Module design JSON'); its surface is\n"
                 "the measurement scene")
      ->required()
      ->type_name("FILE");
  mc->add_option("--iterations", args.iterations,
                 "Number of Monte Carlo trials M, 1 to 10000000")
      ->required()
      ->check(opl::cli::MonteCarloIterationsValidator())
      ->type_name("N");
  mc->add_option("--seed", args.spots.seed,
                 "Seed, 0 to 2^64 - 1; iteration i draws from a seed derived from it and i, so\n"
                 "the same seed gives the same report whatever --threads")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  mc->add_option("--threads", args.threads, "Worker threads, >= 0; 0 = every core")
      ->capture_default_str();
  mc->add_option("--noise-scale", args.noise_scale,
                 "Multiplies the design's spot noise (spot_noise_mm), > 0")
      ->capture_default_str();
  mc->add_option("--weighting", args.weighting,
                 "How each locate weights its spots: 'efficient' (each spot's covariance carried\n"
                 "into its angular residuals, as opl_measure does with sx, sy, sz) or 'unweighted'\n"
                 "(plain angular residuals, as for spots without sigmas)")
      ->capture_default_str()
      ->type_name("W");
  mc->add_flag("--calibration", args.calibration,
               "Monte Carlo of a calibration session instead of a measurement: the screens of\n"
               "`slices` (--depths, --tilt-deg, --curvature), every iteration a noisy session\n"
               "calibrated with opl_calibrate's solver: the spread of every origin, pose, beam\n"
               "direction and separation against the calibration's own uncertainty");
  CLI::Option* mc_depths =
      mc->add_option("--depths", args.depths,
                     "With --calibration: the screen depths, mm (default 750:65:1335)")
          ->type_name("LIST");
  mc->add_option("--tilt-deg", args.tilt_deg, "With --calibration: screen tilt, degrees (see slices)")
      ->capture_default_str();
  mc->add_option("--curvature", args.curvature_per_mm,
                 "With --calibration: screen curvature, 1/mm (see slices)")
      ->capture_default_str();
  CLI::Option* mc_json =
      mc->add_flag("--json", args.json,
                   "Write one JSON object (format opl.monte_carlo_report, docs/uncertainty.md)\n"
                   "instead of the text summary");
  mc->add_flag("--samples", args.samples,
               "With --json: the values of every successful iteration too (sample_iterations;\n"
               "per length samples_mm, scale_factor.samples, per source origin_samples_mm and\n"
               "rotation_samples_rad), in iteration order; about 200 bytes per iteration\n"
               "with two sources")
      ->needs(mc_json);
  mc->add_option("--plot", args.plot_path,
                 "Figure to write, .png, .svg or .pdf (atomically; before anything is printed,\n"
                 "nothing on an error): per length L (the first three) and for s - 1\n"
                 "(ppm) the histogram of the Monte Carlo values (Freedman-Diaconis bins,\n"
                 "10 to 100), the first-order normal density scaled to counts, and the 95 %\n"
                 "coverage intervals: the Monte Carlo's (JCGM 101 7.7.1) and first order\n"
                 "+-1.96 u (dashed)")
      ->type_name("FILE.png|svg|pdf");
  const std::string mc_examples =
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000\n"
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000 --seed 7 \\\n"
      "      --threads 2 --json > mc.json\n"
      "  opl_simulate mc --design examples/staggered_design.json --iterations 5000 \\\n"
      "      --plot mc.png --json --samples > mc_samples.json\n"
      "  opl_simulate mc --design examples/prototype_design.json --iterations 2000 --noise-scale 2\n"
      "  opl_simulate mc --design examples/anisotropic_design.json --iterations 2000 \\\n"
      "      --weighting unweighted\n"
      "  opl_simulate mc --design examples/prototype_design.json --iterations 500 --calibration \\\n"
      "      --depths 750:65:1335\n";
  mc->footer(opl::cli::HelpFooter(mc_examples));

  CLI::App* sweep = app.add_subcommand(
      "sweep",
      "Design study (docs/uncertainty.md, 'Design sweeps'): how the uncertainty of every\n"
      "length L moves with one design parameter. For every value the design is changed in\n"
      "that parameter alone and a measurement Monte Carlo of it runs (as `mc`, the same\n"
      "seed at every value, so neighbouring points differ by the design, not by the draw),\n"
      "with its first-order prediction and Cramer-Rao bound. Writes a CSV (one row per\n"
      "value and length) and, with --plot, a PNG: std of L (mm) and u(L)/L (ppm) against\n"
      "the parameter. Prints a table.\n"
      "\n"
      "Parameters (every source alike):\n"
      "  noise_mm        largest per-axis spot noise sigma, mm (the other axes keep their ratio)\n"
      "  full_angle_deg  full fan angle of every pattern, deg\n"
      "  beams_per_side  n of every pattern (odd)\n"
      "  separation_mm   distance of the first two origins, mm (origins scaled about their\n"
      "                  centroid)\n"
      "  distance_mm     projection distance, mm (the surface moved along the viewing direction)\n"
      "  stagger_deg     layout of two sources: the baseline turned from across (0, side by\n"
      "                  side) towards the viewing direction (45 staggered, 90 in line)\n"
      "  layout          the designs of stagger_deg 0 and 45, named side_by_side and\n"
      "                  staggered: categorical (plotted at 1, 2, ... as markers only)");
  sweep->add_option("--design", args.design_path, "Module design JSON: the base design")
      ->required()
      ->type_name("FILE");
  sweep->add_option("--param", args.param, "The parameter swept (see above)")->required()->type_name("P");
  sweep->add_option("--values", args.values,
                    "Its values: first:step:last (last included) or a comma-separated list")
      ->required()
      ->type_name("LIST");
  sweep->add_option("--out", args.out_path, "Sweep CSV to write (atomically)")->required()->type_name("FILE");
  sweep->add_option("--plot", args.plot_path,
                    "Plot to write, .png, .svg or .pdf (atomically, with the CSV or not at all):\n"
                    "Monte Carlo markers with error bars, first order (solid line with markers),\n"
                    "Cramer-Rao bound (dashed over it); layout: markers only, at ticks named\n"
                    "by the layouts")
      ->type_name("FILE.png|svg|pdf");
  sweep->add_flag("--log-x", args.log_x, "Logarithmic parameter axis in the plot (not for layout)");
  sweep->add_flag("--log-y", args.log_y,
                  "Logarithmic uncertainty axes in the plot (a power law is a straight line)");
  args.iterations = 1000;
  sweep->add_option("--iterations", args.iterations,
                    "Monte Carlo trials per value, 1 to 10000000")
      ->check(opl::cli::MonteCarloIterationsValidator())
      ->capture_default_str()
      ->type_name("N");
  sweep->add_option("--seed", args.spots.seed, "Seed, 0 to 2^64 - 1 (the same at every value)")
      ->check(opl::cli::SeedValidator())
      ->capture_default_str();
  sweep->add_option("--threads", args.threads, "Worker threads, >= 0; 0 = every core")
      ->capture_default_str();
  sweep->add_option("--weighting", args.weighting, "efficient or unweighted (see `mc`)")
      ->capture_default_str()
      ->type_name("W");
  const std::string sweep_examples =
      "  opl_simulate sweep --design examples/staggered_design.json --param noise_mm \\\n"
      "      --values 0.05:0.05:0.3 --out noise.csv --plot noise.png\n"
      "  opl_simulate sweep --design examples/staggered_design.json --param full_angle_deg \\\n"
      "      --values 10:5:45 --iterations 2000 --out angle.csv --plot angle.png --log-x --log-y\n"
      "  opl_simulate sweep --design examples/prototype_design.json --param layout \\\n"
      "      --values side_by_side,staggered --out layout.csv\n";
  sweep->footer(opl::cli::HelpFooter(sweep_examples));

  CLI::App* images = app.add_subcommand(
      "images",
      "Render the images of a scene (docs/formats.md, 'Scene JSON'): every shot is the\n"
      "picture its calibrated camera takes, from its true pose, of the AprilTags\n"
      "(tag36h11) on the walls and of the laser spots of the sources lit in that shot on\n"
      "the module's surface (include/opl/lab/render_scene.h has the model). Tags: exact\n"
      "area-integrated edges, the scene's levels and blur. Spots: each beam's hit on the\n"
      "surface, drawn where it is in front of the camera, inside the image and on a\n"
      "surface facing the camera, as the projected disc of spots.diameter_mm (elliptical\n"
      "where the surface is oblique), with speckle; then shot and read noise once.\n"
      "\n"
      "Writes into DIR (created if missing), each file atomically:\n"
      "  <shot.file>   one PNG per shot (8 or 16 bit gray, image.bit_depth)\n"
      "  truth.json    the ground truth (format opl.scene_truth, docs/formats.md, 'Scene\n"
      "                truth JSON'): 3D tag centres and corners, 3D spot points by source\n"
      "                and beam (mm), and per shot the tag corner and spot centre pixels\n"
      "                (OpenCV convention: (0, 0) is the centre of the top-left pixel)\n"
      "and prints one line per image on stdout. On any error no image of this run is\n"
      "left in DIR. A progress bar is drawn on stderr when stderr is a terminal.\n"
      "Memory: about 18 bytes per pixel per thread (an 18 MP image: 330 MB).");
  images->add_option("--scene", args.scene_path, "Scene JSON (docs/formats.md, 'Scene JSON')")
      ->required()
      ->type_name("FILE");
  images->add_option("--out", args.out_path, "Output folder (created if missing)")
      ->required()
      ->type_name("DIR");
  images->add_option("--shots", args.shots,
                     "Render only these shots: comma-separated indices into the scene's shots\n"
                     "(default: all); truth.json then lists those shots only")
      ->type_name("LIST");
  CLI::Option* images_threads =
      images->add_option("--threads", args.threads,
                         "Shots rendered at once, >= 0; 0 = every core (default 1: memory)");
  images_threads->type_name("T");
  const std::string images_examples =
      "  opl_simulate images --scene examples/scene_small.json --out lab\n"
      "  opl_simulate images --scene examples/scene_small.json --out lab --shots 0,4 --threads 2\n";
  images->footer(opl::cli::HelpFooter(images_examples));

  if (std::optional<int> code = opl::cli::ParseCommandLine(app, argc, argv)) return *code;
  if (std::optional<int> code = opl::cli::RefuseOutputsOverInputs(
          kTool, {{"--design", args.design_path}, {"--scene", args.scene_path}},
          {{"--out", args.out_path}, {"--plot", args.plot_path}})) {
    return *code;
  }
  {
    // The provenance hashes the inputs that exist (a missing one is its
    // reader's to report, with its own message).
    std::vector<std::string> inputs;
    for (const std::string& path : {args.design_path, args.scene_path}) {
      std::error_code ec;
      if (!path.empty() && std::filesystem::is_regular_file(path, ec)) inputs.push_back(path);
    }
    if (std::optional<int> code =
            opl::cli::MakeRunProvenance(kTool, argc, argv, inputs, &args.provenance)) {
      return *code;
    }
  }
  if (images->parsed()) {
    if (images_threads->count() == 0) args.threads = 1;
    return ImagesCommand(args);
  }
  if (mc->parsed()) {
    args.depths_given = mc_depths->count() > 0;
    return MonteCarloCommand(args);
  }
  if (sweep->parsed()) return SweepCommand(args);
  if (spots->parsed()) return SimulateSpotsCommand(args);
  if (slices->parsed()) {
    args.depths_given = depths->count() > 0;
    return SimulateSlicesCommand(args);
  }
  return CalibrationCommand(args);
}

}  // namespace

int main(int argc, char** argv) {
  return opl::cli::RunTool(kTool, [&] { return Run(argc, argv); });
}
