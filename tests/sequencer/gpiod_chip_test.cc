// The libgpiod backend: built, linked and exercised. Against the kernel's
// gpio-sim (configfs) where the machine has it; skipped with the reason
// where it has not.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "opl/sequencer/gpio.h"

namespace opl::sequencer {
namespace {

constexpr const char* kConfigfs = "/sys/kernel/config";
constexpr const char* kGpioSimDir = "/sys/kernel/config/gpio-sim";

bool IsDir(const std::string& path) {
  struct stat st{};
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool ConfigfsMounted() {
  std::ifstream mounts("/proc/mounts");
  for (std::string line; std::getline(mounts, line);) {
    if (line.find(std::string(" ") + kConfigfs + " configfs ") != std::string::npos) return true;
  }
  return false;
}

bool WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.flush();
  return static_cast<bool>(out);
}

std::string ReadFirstLine(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

TEST(GpiodChip, MissingChipIsAnErrorNotACrash) {
  auto chip = OpenGpiodChip("opl-no-such-gpiochip");
  ASSERT_FALSE(chip.ok());
  EXPECT_NE(chip.status().message().find("opl-no-such-gpiochip"), std::string::npos) << chip.status().ToString();
  EXPECT_FALSE(OpenGpiodChip("").ok());
}

// A gpio-sim chip made through configfs, removed again on destruction.
class GpioSimChip {
 public:
  // Returns an empty string on success, else why the chip cannot be made.
  std::string Create(unsigned num_lines) {
    dir_ = std::string(kGpioSimDir) + "/opl-test-" + std::to_string(::getpid());
    if (::mkdir(dir_.c_str(), 0755) != 0) return "mkdir " + dir_ + " failed (errno " + std::to_string(errno) + ")";
    bank_ = dir_ + "/bank0";
    if (::mkdir(bank_.c_str(), 0755) != 0) return "mkdir " + bank_ + " failed";
    if (!WriteFile(bank_ + "/num_lines", std::to_string(num_lines))) return "cannot set num_lines";
    if (!WriteFile(dir_ + "/live", "1")) return "cannot make the chip live";
    live_ = true;
    chip_name_ = ReadFirstLine(bank_ + "/chip_name");
    dev_name_ = ReadFirstLine(dir_ + "/dev_name");
    if (chip_name_.empty() || dev_name_.empty()) return "no chip_name/dev_name after going live";
    return "";
  }
  ~GpioSimChip() {
    if (live_) WriteFile(dir_ + "/live", "0");
    if (!bank_.empty()) ::rmdir(bank_.c_str());
    if (!dir_.empty()) ::rmdir(dir_.c_str());
  }
  const std::string& chip_name() const { return chip_name_; }
  // Electrical level the simulator sees on `offset`: 0, 1 or -1 if unknown.
  int Level(unsigned offset) const {
    const std::string v = ReadFirstLine("/sys/devices/platform/" + dev_name_ + "/" + chip_name_ + "/sim_gpio" +
                                        std::to_string(offset) + "/value");
    return v == "1" ? 1 : v == "0" ? 0 : -1;
  }

 private:
  std::string dir_, bank_, chip_name_, dev_name_;
  bool live_ = false;
};

TEST(GpiodChip, DrivesKernelGpioSimLines) {
  if (!IsDir(kConfigfs) || !ConfigfsMounted()) {
    GTEST_SKIP() << "no configfs: nothing mounted at " << kConfigfs
                 << " (kernel without CONFIG_CONFIGFS_FS, or mount -t configfs none " << kConfigfs << ")";
  }
  if (!IsDir(kGpioSimDir)) {
    // Loading the module needs root too; try once, quietly.
    if (::geteuid() == 0) (void)std::system("modprobe gpio-sim >/dev/null 2>&1");
    if (!IsDir(kGpioSimDir)) GTEST_SKIP() << "no gpio-sim module: " << kGpioSimDir << " does not exist (CONFIG_GPIO_SIM)";
  }
  if (::geteuid() != 0) GTEST_SKIP() << "not root: creating a gpio-sim chip through configfs needs root";

  GpioSimChip sim;
  const std::string why = sim.Create(8);
  ASSERT_TRUE(why.empty()) << why;

  auto chip = OpenGpiodChip(sim.chip_name());
  ASSERT_TRUE(chip.ok()) << chip.status().ToString();
  GpioChip& c = *chip.value();
  ASSERT_TRUE(c.RequestOutputs({{1, false, "laser_a"}, {2, false, "laser_b"}, {3, false, "blocker"}, {4, true, "trigger"}},
                               "opl-test")
                  .ok());
  // Requested inactive: low, and high for the active-low trigger.
  EXPECT_EQ(sim.Level(1), 0);
  EXPECT_EQ(sim.Level(2), 0);
  EXPECT_EQ(sim.Level(4), 1);
  ASSERT_TRUE(c.SetActive(0, true).ok());
  ASSERT_TRUE(c.SetActive(3, true).ok());
  EXPECT_EQ(sim.Level(1), 1);
  EXPECT_EQ(sim.Level(4), 0);
  ASSERT_TRUE(c.SetActive(0, false).ok());
  EXPECT_EQ(sim.Level(1), 0);
  // A second request of the same lines must fail (another daemon).
  auto second = OpenGpiodChip(sim.chip_name());
  ASSERT_TRUE(second.ok());
  EXPECT_FALSE(second.value()->RequestOutputs({{1, false, "laser_a"}}, "opl-test2").ok());
  c.Release();
  // Beyond the chip.
  auto third = OpenGpiodChip(sim.chip_name());
  ASSERT_TRUE(third.ok());
  EXPECT_EQ(third.value()->RequestOutputs({{8, false, "laser_a"}}, "opl-test3").code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace opl::sequencer
