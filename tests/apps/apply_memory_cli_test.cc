// Peak memory of opl_measure --apply on large binary PLY files: the scaling
// streams, so the peak resident set of the tool does not grow with the file.
// The tool runs as a child process and its own peak (wait4's ru_maxrss) is
// read, for a 10-point file (the baseline: libraries, the measurement) and
// for 1 million points of 39 bytes (39 MB, which a reader holding the file
// would need on top of the baseline), then for 10 million points (390 MB; the
// issue's target: under 100 MB peak). About 1.5 s in all (page cache); the
// files are removed as soon as they are used.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>

#include "io/temp_dir.h"

namespace opl {
namespace {

using testing_support::TempDir;

struct ChildRun {
  int exit_code = -1;
  long max_rss_kib = 0;
};

// Runs opl_measure with `args` (stdout, stderr to /dev/null) and returns its
// exit code and its own peak resident set size.
ChildRun RunMeasure(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  std::string exe = OPL_MEASURE_EXE;
  argv.push_back(exe.data());
  std::vector<std::string> copy = args;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  ChildRun run;
  int status = 0;
  struct rusage usage;
  if (pid > 0 && ::wait4(pid, &status, 0, &usage) == pid) {
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    run.max_rss_kib = usage.ru_maxrss;
  }
  return run;
}

// A binary PLY of `n` vertices: double x, y, z; float nx, ny, nz; uchar
// red, green, blue (39 bytes each), written in 1 MiB blocks.
void WritePly(const std::string& path, long long n) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << n
      << "\nproperty double x\nproperty double y\nproperty double z\n"
         "property float nx\nproperty float ny\nproperty float nz\n"
         "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  constexpr int kRecord = 39;
  std::vector<char> block(static_cast<size_t>(kRecord) * 26000);
  long long written = 0;
  while (written < n) {
    const long long k = std::min<long long>(n - written, 26000);
    for (long long i = 0; i < k; ++i) {
      char* r = block.data() + i * kRecord;
      const double xyz[3] = {0.001 * static_cast<double>(written + i), 1.0, -2.0};
      const float normal[3] = {0.0f, 0.6f, 0.8f};
      std::memcpy(r, xyz, 24);
      std::memcpy(r + 24, normal, 12);
      r[36] = 1;
      r[37] = 2;
      r[38] = 3;
    }
    out.write(block.data(), static_cast<std::streamsize>(k * kRecord));
    written += k;
  }
}

ChildRun ApplyTo(const TempDir& dir, long long n) {
  const std::string in = dir.File("cloud_" + std::to_string(n) + ".ply");
  WritePly(in, n);
  const std::string examples = OPL_EXAMPLES_DIR;
  ChildRun run = RunMeasure({"--calibration", examples + "/prototype_calibration.json", "--spots",
                             examples + "/prototype_spots.csv", "--apply", in, "--out",
                             dir.File("scaled_" + std::to_string(n) + ".ply")});
  std::remove(in.c_str());
  std::remove(dir.File("scaled_" + std::to_string(n) + ".ply").c_str());
  return run;
}

TEST(ApplyMemory, OneMillionPointsTakeNoMoreThanTen) {
  TempDir dir;
  const ChildRun small = ApplyTo(dir, 10);
  const ChildRun large = ApplyTo(dir, 1000000);
  ASSERT_EQ(small.exit_code, 0);
  ASSERT_EQ(large.exit_code, 0);
  // The two 4 MiB buffers and some slack; the file is 39 MB.
  RecordProperty("max_rss_kib_10_points", std::to_string(small.max_rss_kib));
  RecordProperty("max_rss_kib_1m_points", std::to_string(large.max_rss_kib));
  EXPECT_LT(large.max_rss_kib - small.max_rss_kib, 16 * 1024)
      << "10 points: " << small.max_rss_kib << " KiB, 1e6 points: " << large.max_rss_kib << " KiB";
}

TEST(ApplyMemory, TenMillionPointsUnder100MB) {
  TempDir dir;
  const ChildRun run = ApplyTo(dir, 10000000);
  ASSERT_EQ(run.exit_code, 0);
  RecordProperty("max_rss_kib_10m_points", std::to_string(run.max_rss_kib));
  std::printf("peak RSS of opl_measure --apply on 10 million points (390 MB PLY): %ld KiB\n",
              run.max_rss_kib);
  EXPECT_LT(run.max_rss_kib, 100 * 1000);  // 100 MB
}

}  // namespace
}  // namespace opl
