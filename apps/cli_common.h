// What every OPL command-line tool shares: exit codes, the --help footer that
// documents them, CLI11 parsing with usage errors mapped to exit code 2, and
// one-line error messages "<tool>: <message>" on stderr (docs/cli.md).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "opl/core/status.h"
#include "opl/io/provenance.h"
#include "opl/pipeline/image_front_end.h"

namespace opl {
namespace cli {

// Exit codes of every tool (docs/cli.md).
enum ExitCode : int {
  kExitOk = 0,
  kExitInternalError = 1,  // an unexpected exception (a bug): please report
  kExitUsage = 2,          // bad command line: unknown/missing option, not a number
  kExitBadInput = 3,       // unreadable or malformed input file, invalid value
  kExitNoSolution = 4,     // valid data that do not determine a pose or scale
  kExitWriteFailed = 5,    // an output file could not be written
};

// The exit-code table and documentation pointers for a tool's --help footer,
// after the tool's `examples` (already formatted lines).
std::string HelpFooter(const std::string& examples);

// Exit code for a Status from reading or processing inputs: NoSolution -> 4,
// every other failure (InvalidArgument, ParseError, IoError) -> 3.
int ExitCodeForInputStatus(const Status& status);

// Prints "<tool>: <message>" on stderr and returns `exit_code`.
int Fail(const std::string& tool, const std::string& message, int exit_code);
// Fail with the status's message and ExitCodeForInputStatus.
int FailInput(const std::string& tool, const Status& status);
// Fail with the status's message and kExitWriteFailed.
int FailWrite(const std::string& tool, const Status& status);

// Parses the command line. Returns std::nullopt when the tool should go on, or
// the exit code to return now: 0 after --help (printed on stdout), 2 after a
// usage error (printed on stderr as "<tool>: <error> (see --help)").
std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv);

// CLI11 check of an option giving the beams per side n of a grid: an integer,
// odd, in [3, kMaxBeamsPerSide] (model/beam_pattern.h); else a usage error
// (exit 2) "--beams-per-side: must be odd and in [3, 201], got 100001".
CLI::Validator BeamsPerSideValidator();

// CLI11 check of a --seed: decimal digits only, at most 2^64 - 1 (CLI11 alone
// took "-1" and anything beyond 2^64 - 1 as 2^64 - 1); else a usage error
// "--seed: not a seed in 0..18446744073709551615: '-1'".
CLI::Validator SeedValidator();

// CLI11 check of an --iterations: an integer in [1, kMaxMonteCarloIterations]
// (uncertainty/monte_carlo.h); beyond, a usage error naming the option.
// (0 and negative values are left to the tool, which refuses them.)
CLI::Validator MonteCarloIterationsValidator();

// True when `a` and `b` name the same file: by filesystem identity
// (std::filesystem::equivalent: hard links, symlinks, "./x" and "x") when both
// exist, else by their weakly canonical paths. Empty paths name nothing.
bool SameFile(const std::string& a, const std::string& b);

// An option naming a file, e.g. {"--spots", "s.csv"}; an empty path is an
// option not given.
struct NamedPath {
  std::string option;
  std::string path;
};
// Refuses (usage error, exit 2, before anything is read or written) an output
// naming the same file as an input or as another output:
//   "--out 's.csv' is the same file as --spots: refusing to overwrite an input"
// std::nullopt when every output is distinct.
std::optional<int> RefuseOutputsOverInputs(const std::string& tool,
                                           const std::vector<NamedPath>& inputs,
                                           const std::vector<NamedPath>& outputs);

// Ceres reports through glog (warnings such as "Linear solver failure"):
// silenced in every tool, whose own messages say what failed.
// QuietSolverLogging (called by RunTool) initialises glog logging to stderr
// only at FATAL; ShowSolverLogging (a tool's --verbose) lets every level
// through.
void QuietSolverLogging(const std::string& tool);
void ShowSolverLogging();
// The options opl_measure and opl_calibrate share for --images runs:
// --spot-channel (checked by CLI11: usage error 2), --no-dark-frames,
// --no-dark-frame-exposure, --force, --verbose.
struct ImageRunArgs {
  std::string spot_channel = "red";
  bool no_dark_frames = false;
  bool no_dark_frame_exposure = false;
  bool force = false;
  bool verbose = false;
};
void AddImageRunOptions(CLI::App& app, ImageRunArgs* args);
// Copies the channel, --no-dark-frames, --no-dark-frame-exposure and --force
// into the front end's options.
void ApplyImageRunOptions(const ImageRunArgs& args, FrontEndOptions* options);
// Runs `body` (after QuietSolverLogging), turning an escaping exception into "<tool>: internal error:
// ..." and kExitInternalError. The library itself does not throw on bad input;
// this is a last line of defence (e.g. std::bad_alloc).
int RunTool(const std::string& tool, const std::function<int()>& body);

// Writes `text` to stdout and flushes; kExitWriteFailed (with a message) when
// stdout cannot be written (e.g. a closed pipe or a full disk), else kExitOk.
int PrintToStdout(const std::string& tool, const std::string& text);

// The run's provenance (io/provenance.h): the tool, version, time, command
// line and the SHA-256 of every input path in `inputs` ("" skipped). A folder
// among them stands for its regular files (sorted; a COLMAP model). An
// unreadable input gives its message and exit 3: std::nullopt when fine.
std::optional<int> MakeRunProvenance(const std::string& tool, int argc, const char* const* argv,
                                     const std::vector<std::string>& inputs, Provenance* out);

// The image files of a scene's shots that exist in `images_dir`, in shot
// order, for the provenance's inputs (a missing image is the front end's to
// report, not the provenance's).
std::vector<std::string> ExistingShotImages(const Scene& scene, const std::string& images_dir);

// PrintToStdout of a JSON report with the run's provenance as its last member
// (what --json prints is often saved as a file: it says how it was made too).
int PrintJsonToStdout(const std::string& tool, const std::string& json,
                      const Provenance& provenance);

}  // namespace cli
}  // namespace opl
