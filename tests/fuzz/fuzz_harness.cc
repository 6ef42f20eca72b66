#include "fuzz/fuzz_harness.h"

#include "opl/core/message_text.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

namespace opl {
namespace fuzz {

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_UNDEFINED__)
constexpr double kDefaultSlowSeconds = 10.0;
#else
constexpr double kDefaultSlowSeconds = 2.0;
#endif

std::string Env(const char* name) {
  const char* value = std::getenv(name);
  return value == nullptr ? std::string() : std::string(value);
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void AppendFiles(const std::filesystem::path& dir, std::vector<CorpusEntry>* entries) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) return;
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.is_regular_file()) names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) entries->push_back({name, ReadFile((dir / name).string())});
}

// "bit_flip+truncate".
std::string OpsText(const std::vector<MutationOp>& ops) {
  std::string text;
  for (MutationOp op : ops) text += (text.empty() ? "" : "+") + std::string(MutationOpName(op));
  return text.empty() ? "none" : text;
}

// Saves a failing input and its line in findings.txt; returns the file path.
// The file keeps the extension of the seed it was made from (a target may
// choose the format by it), so that a findings folder replays as a corpus.
std::string SaveFinding(const FuzzSettings& settings, const std::string& format,
                        const std::string& case_name, const std::string& seed_name,
                        const std::string& input, const std::string& line) {
  if (settings.findings_dir.empty()) return "";
  const std::filesystem::path dir = std::filesystem::path(settings.findings_dir) / format;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  std::string extension = std::filesystem::path(seed_name).extension().string();
  if (extension.empty()) extension = ".bin";
  const std::string path = (dir / (case_name + extension)).string();
  std::ofstream(path, std::ios::binary) << input;
  std::ofstream(std::filesystem::path(settings.findings_dir) / "findings.txt", std::ios::app)
      << format << " " << case_name << " " << line << "\n";
  return path;
}

// Aborts the run when one input takes longer than `seconds`, after saving it
// (a hang cannot be a gtest failure: the call never returns).
class Watchdog {
 public:
  Watchdog(const FuzzSettings& settings, std::string format)
      : settings_(settings), format_(std::move(format)), thread_([this] { Watch(); }) {}
  ~Watchdog() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  void Start(const std::string& case_name, const std::string& seed_name, const std::string& input) {
    std::lock_guard<std::mutex> lock(mutex_);
    case_name_ = case_name;
    seed_name_ = seed_name;
    input_ = input;
    started_ = std::chrono::steady_clock::now();
    running_ = true;
  }
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    running_ = false;
  }

 private:
  void Watch() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      wake_.wait_for(lock, std::chrono::milliseconds(200));
      if (!running_) continue;
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
      if (seconds > settings_.hang_seconds) {
        const std::string line = "hang: no answer after " + std::to_string(seconds) + " s";
        const std::string path = SaveFinding(settings_, format_, case_name_, seed_name_, input_, line);
        std::fprintf(stderr, "fuzz %s %s: %s%s%s\n", format_.c_str(), case_name_.c_str(),
                     line.c_str(), path.empty() ? "" : "; input saved as ", path.c_str());
        std::fflush(stderr);
        std::abort();
      }
    }
  }

  const FuzzSettings& settings_;
  const std::string format_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false, running_ = false;
  std::string case_name_, seed_name_, input_;
  std::chrono::steady_clock::time_point started_;
  std::thread thread_;  // last: started after the members it reads
};

std::string MessageProblem(const std::string& message, const std::string& input_name) {
  if (message.empty()) return "empty error message";
  for (const char c : message) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02x", u);
      return std::string("message holds the control character ") + hex;
    }
  }
  size_t named = 0, own = message.size();
  if (!input_name.empty()) {
    for (size_t at = message.find(input_name); at != std::string::npos;
         at = message.find(input_name, at + input_name.size())) {
      ++named;
      own -= input_name.size();
    }
  }
  if (!input_name.empty() && named == 0) return "message does not name the input";
  if (own > 1000) return "message of " + std::to_string(message.size()) + " bytes";
  return "";
}

}  // namespace

FuzzSettings FuzzSettings::FromEnvironment(int default_iterations) {
  FuzzSettings s;
  s.iterations = default_iterations;
  s.slow_seconds = kDefaultSlowSeconds;
  if (const std::string v = Env("OPL_FUZZ_ITERATIONS"); !v.empty()) s.iterations = std::stoi(v);
  if (const std::string v = Env("OPL_FUZZ_SEED"); !v.empty()) s.seed = std::stoull(v);
  s.findings_dir = Env("OPL_FUZZ_FINDINGS");
  s.replay_dir = Env("OPL_FUZZ_REPLAY");
  if (const std::string v = Env("OPL_FUZZ_SLOW_SECONDS"); !v.empty()) s.slow_seconds = std::stod(v);
  if (const std::string v = Env("OPL_FUZZ_HANG_SECONDS"); !v.empty()) s.hang_seconds = std::stod(v);
  return s;
}

std::string CorpusDir() {
  const std::string root = Env("OPL_SOURCE_DIR");
  return (root.empty() ? std::string(".") : root) + "/tests/fuzz/corpus";
}

std::vector<CorpusEntry> LoadCorpus(const std::string& format, const FuzzSettings& settings) {
  std::vector<CorpusEntry> entries;
  AppendFiles(std::filesystem::path(CorpusDir()) / format, &entries);
  if (!settings.replay_dir.empty()) {
    AppendFiles(std::filesystem::path(settings.replay_dir) / format, &entries);
  }
  return entries;
}

std::string CheckErrorMessage(const std::string& message, const std::string& input_name) {
  const std::string problem = MessageProblem(message, input_name);
  return problem.empty() ? "" : problem + ": " + QuoteForMessage(message, 300);
}

FuzzStats RunFuzz(const std::string& format, InputKind kind, const FuzzSettings& settings,
                  const FuzzTarget& target, size_t max_size) {
  const std::vector<CorpusEntry> corpus = LoadCorpus(format, settings);
  EXPECT_FALSE(corpus.empty()) << "no seeds in " << CorpusDir() << "/" << format;
  return RunFuzzOnCorpus(format, corpus, kind, settings, target, max_size);
}

FuzzStats RunFuzzOnCorpus(const std::string& format, const std::vector<CorpusEntry>& corpus,
                          InputKind kind, const FuzzSettings& settings, const FuzzTarget& target,
                          size_t max_size) {
  FuzzStats stats;
  if (corpus.empty()) return stats;
  std::vector<std::string> seeds;
  for (const CorpusEntry& e : corpus) seeds.push_back(e.bytes);

  const Mutator mutator(max_size);
  Watchdog watchdog(settings, format);
  auto run_one = [&](const std::string& case_name, const std::string& input,
                     const std::string& seed_name, const std::string& ops) {
    TargetResult result;
    watchdog.Start(case_name, seed_name, input);
    const auto start = std::chrono::steady_clock::now();
    try {
      result = target(input, seed_name);
    } catch (const std::exception& e) {
      result.problem = std::string("exception thrown out of the reader: ") + e.what();
    } catch (...) {
      result.problem = "unknown exception thrown out of the reader";
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    watchdog.Stop();
    ++stats.inputs;
    stats.accepted += result.accepted;
    stats.total_seconds += seconds;
    stats.max_seconds = std::max(stats.max_seconds, seconds);
    if (result.problem.empty() && seconds > settings.slow_seconds) {
      result.problem = "slow: " + std::to_string(seconds) + " s (limit " +
                       std::to_string(settings.slow_seconds) + " s)";
    }
    if (result.problem.empty()) return;
    ++stats.problems;
    const std::string line = "from " + seed_name + " by " + ops + ": " + result.problem;
    const std::string saved = SaveFinding(settings, format, case_name, seed_name, input, line);
    ADD_FAILURE() << "fuzz " << format << " case " << case_name << " (OPL_FUZZ_SEED="
                  << settings.seed << ") " << line
                  << (saved.empty() ? "" : "\n  input saved as " + saved);
  };

  if (settings.run_seeds) {
    for (const CorpusEntry& e : corpus) run_one("seed_" + e.name, e.bytes, e.name, "none");
  }
  for (int i = 0; i < settings.iterations; ++i) {
    FuzzRng rng(CaseSeed(settings.seed, format, static_cast<uint64_t>(i)));
    const CorpusEntry& base = corpus[rng.Below(corpus.size())];
    std::vector<MutationOp> ops;
    const std::string input = mutator.Mutate(base.bytes, seeds, kind, rng, &ops);
    run_one(std::to_string(settings.seed) + "_" + std::to_string(i), input, base.name,
            OpsText(ops));
  }
  std::printf("fuzz %s: %d inputs (%zu seeds%s, %d mutated, seed %llu), %d read, %d findings, "
              "slowest %.3f s, total %.2f s\n",
              format.c_str(), stats.inputs, corpus.size(), settings.run_seeds ? "" : " not run",
              settings.iterations,
              static_cast<unsigned long long>(settings.seed), stats.accepted, stats.problems,
              stats.max_seconds, stats.total_seconds);
  return stats;
}

}  // namespace fuzz
}  // namespace opl
