#include "cli_common.h"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <limits>
#include <string>

#include <glog/logging.h>

#include "opl/core/message_text.h"
#include "opl/core/version.h"
#include "opl/io/provenance_stamp.h"
#include "opl/model/beam_pattern.h"
#include "opl/uncertainty/monte_carlo.h"

namespace opl {
namespace cli {

std::string HelpFooter(const std::string& examples) {
  return "\nExamples:\n" + examples +
         "\nExit codes:\n"
         "  0  success\n"
         "  1  internal error (a bug; please report it)\n"
         "  2  usage error (unknown or missing option, option value not of its type\n"
         "     or out of its range, an output naming an input)\n"
         "  3  bad input (file unreadable or malformed, invalid value); the message\n"
         "     names the file and line or field\n"
         "  4  no solution (valid data that do not determine a pose or a scale)\n"
         "  5  an output could not be written (nothing is left half-written)\n"
         "On any error one line '<tool>: <message>' goes to stderr and no output\n"
         "file is created or changed.\n"
         "\nFile formats: docs/formats.md; tools and options: docs/cli.md (OPL source tree).\n";
}

int ExitCodeForInputStatus(const Status& status) {
  if (status.ok()) return kExitOk;
  return status.code() == StatusCode::kNoSolution ? kExitNoSolution : kExitBadInput;
}

int Fail(const std::string& tool, const std::string& message, int exit_code) {
  // One line, whatever an input file put in the message (issue 19 item 7).
  std::cerr << tool << ": " << OneLineMessage(message) << std::endl;
  return exit_code;
}

int FailInput(const std::string& tool, const Status& status) {
  return Fail(tool, status.message(), ExitCodeForInputStatus(status));
}

int FailWrite(const std::string& tool, const Status& status) {
  return Fail(tool, status.message(), kExitWriteFailed);
}

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv) {
  app.set_version_flag("--version", app.get_name() + " " + VersionString(),
                       "Print the tool's version and the commit it was built from, and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);  // prints the help on stdout, returns 0
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return Fail(app.get_name(), std::string(e.what()) + " (see --help)", kExitUsage);
  }
  return std::nullopt;
}

CLI::Validator BeamsPerSideValidator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        long long n = 0;
        size_t used = 0;
        try {
          n = std::stoll(value, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == 0 || used != value.size()) return "not an integer: '" + value + "'";
        return BeamsPerSideProblem(n);
      },
      "ODD N IN [3, " + std::to_string(kMaxBeamsPerSide) + "]");
}

CLI::Validator SeedValidator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        uint64_t seed = 0;
        const char* end = value.data() + value.size();
        const bool digits = !value.empty() && std::all_of(value.begin(), value.end(), [](char c) {
          return c >= '0' && c <= '9';
        });
        const auto [ptr, ec] = std::from_chars(value.data(), end, seed);
        if (digits && ec == std::errc() && ptr == end) return "";
        return "not a seed in 0.." + std::to_string(std::numeric_limits<uint64_t>::max()) +
               ": '" + value + "'";
      },
      "0..2^64-1");
}

CLI::Validator MonteCarloIterationsValidator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        long long m = 0;
        const char* end = value.data() + value.size();
        const auto [ptr, ec] = std::from_chars(value.data(), end, m);
        if (ec == std::errc::result_out_of_range || (ec == std::errc() && ptr == end &&
                                                     m > kMaxMonteCarloIterations)) {
          return "at most " + std::to_string(kMaxMonteCarloIterations) +
                 " iterations (docs/uncertainty.md), got " + value;
        }
        return "";  // not a number: CLI11's own error; < 1: the tool's
      },
      "");
}

bool SameFile(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty()) return false;
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) {
    const bool same = fs::equivalent(a, b, ec);
    if (!ec) return same;
  }
  const fs::path ca = fs::weakly_canonical(fs::absolute(a, ec), ec);
  if (ec) return a == b;
  const fs::path cb = fs::weakly_canonical(fs::absolute(b, ec), ec);
  if (ec) return a == b;
  return ca == cb;
}

std::optional<int> RefuseOutputsOverInputs(const std::string& tool,
                                           const std::vector<NamedPath>& inputs,
                                           const std::vector<NamedPath>& outputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& out = outputs[i];
    if (out.path.empty()) continue;
    for (const NamedPath& in : inputs) {
      if (SameFile(out.path, in.path)) {
        return Fail(tool,
                    out.option + " '" + out.path + "' is the same file as " + in.option +
                        ": refusing to overwrite an input (see --help)",
                    kExitUsage);
      }
    }
    for (size_t j = 0; j < i; ++j) {
      if (SameFile(out.path, outputs[j].path)) {
        return Fail(tool,
                    out.option + " '" + out.path + "' is the same file as " + outputs[j].option +
                        ": each output needs its own file (see --help)",
                    kExitUsage);
      }
    }
  }
  return std::nullopt;
}

void QuietSolverLogging(const std::string& tool) {
  // glog keeps the pointer it is given: a string that outlives main.
  static const std::string* const name = new std::string(tool);
  static const bool initialised = [] {
    FLAGS_logtostderr = true;  // never log files in /tmp
    FLAGS_minloglevel = google::GLOG_FATAL;
    google::InitGoogleLogging(name->c_str());
    return true;
  }();
  (void)initialised;
}

void ShowSolverLogging() { FLAGS_minloglevel = google::GLOG_INFO; }

void AddImageRunOptions(CLI::App& app, ImageRunArgs* args) {
  app.add_option("--spot-channel", args->spot_channel,
                 "With --images, colour photographs: the channel in which laser spots are\n"
                 "detected: red (red lasers, the default), green, blue, luma, or\n"
                 "red-minus-green (R - G, at least 0: white lamps and highlights cancel, a\n"
                 "red laser keeps ~90% of its contrast); tags are always detected in luma,\n"
                 "grey images used as they are (docs/images.md)")
      ->check(CLI::IsMember({"red", "green", "blue", "luma", "red-minus-green"}))
      ->capture_default_str();
  app.add_flag("--no-dark-frames", args->no_dark_frames,
               "With --images: do not subtract laser-off shots (\"lasers\": [] in the scene)\n"
               "from the lit shots of the same camera and slice before detecting spots\n"
               "(they are subtracted by default when the tags show the camera did not move;\n"
               "docs/images.md, 'Laser-off frames')");
  app.add_flag("--no-dark-frame-exposure", args->no_dark_frame_exposure,
               "With --images: subtract each laser-off shot as it is, without measuring its\n"
               "exposure against the lit shot's (by default a laser-off shot whose exposure\n"
               "differs, from automatic exposure or flickering light, is scaled to the lit\n"
               "shot's first, with a note; docs/images.md, 'Laser-off frames')");
  app.add_flag("--force", args->force,
               "With --images: measure even when the tag corners scatter more than 3 times\n"
               "what their covariances say (refused otherwise, exit 4: wrong intrinsics, a\n"
               "camera that moved); the report then carries a warning");
  app.add_flag("--verbose", args->verbose,
               "Show the solvers' own messages (Ceres, on stderr; silenced by default) and,\n"
               "with --images, the bundle adjustment's report on stderr");
}

void ApplyImageRunOptions(const ImageRunArgs& args, FrontEndOptions* options) {
  const Result<SpotChannel> channel = ParseSpotChannel(args.spot_channel);
  if (channel.ok()) options->spot_channel = *channel;  // CLI11 checked it
  options->force = args.force;
  options->use_dark_frames = !args.no_dark_frames;
  options->match_dark_frame_exposure = !args.no_dark_frame_exposure;
}

int RunTool(const std::string& tool, const std::function<int()>& body) {
  QuietSolverLogging(tool);
  try {
    return body();
  } catch (const std::exception& e) {
    return Fail(tool, std::string("internal error: ") + e.what(), kExitInternalError);
  } catch (...) {
    return Fail(tool, "internal error: unknown exception", kExitInternalError);
  }
}

std::optional<int> MakeRunProvenance(const std::string& tool, int argc, const char* const* argv,
                                     const std::vector<std::string>& inputs, Provenance* out) {
  std::vector<std::string> files;
  for (const std::string& path : inputs) {
    if (path.empty()) continue;
    std::error_code ec;
    if (!std::filesystem::is_directory(path, ec)) {
      files.push_back(path);
      continue;
    }
    std::vector<std::string> inside;
    for (const auto& entry : std::filesystem::directory_iterator(path, ec)) {
      if (entry.is_regular_file(ec)) inside.push_back(entry.path().string());
    }
    std::sort(inside.begin(), inside.end());
    files.insert(files.end(), inside.begin(), inside.end());
  }
  Result<Provenance> provenance = MakeProvenance(tool, argc, argv, files);
  if (!provenance.ok()) return FailInput(tool, provenance.status());
  *out = std::move(*provenance);
  return std::nullopt;
}

int PrintJsonToStdout(const std::string& tool, const std::string& json,
                      const Provenance& provenance) {
  Result<std::string> stamped = StampProvenance("stdout.json", json, provenance);
  if (!stamped.ok()) return Fail(tool, "internal error: " + stamped.status().message(), kExitInternalError);
  return PrintToStdout(tool, *stamped);
}

int PrintToStdout(const std::string& tool, const std::string& text) {
  std::cout << text;
  std::cout.flush();
  if (!std::cout) return Fail(tool, "cannot write to standard output", kExitWriteFailed);
  return kExitOk;
}

std::vector<std::string> ExistingShotImages(const Scene& scene, const std::string& images_dir) {
  std::vector<std::string> files;
  for (const SceneShot& shot : scene.shots) {
    const std::filesystem::path image = std::filesystem::path(images_dir) / shot.file;
    std::error_code ec;
    if (std::filesystem::is_regular_file(image, ec)) files.push_back(image.string());
  }
  return files;
}

}  // namespace cli
}  // namespace opl
