// Configuration parsing and validation: the shipped examples are valid, and
// every rejection names the field, its value and the constraint.
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "opl/sequencer/config.h"

namespace opl::sequencer {
namespace {

const char* kMinimal = R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2},
                                      "blocker": {"offset": 3}, "trigger": {"offset": 4, "active_low": true}}})";

std::string SourceDir() {
  const char* d = std::getenv("OPL_SOURCE_DIR");
  return d != nullptr ? d : OPL_TEST_SOURCE_DIR_FALLBACK;
}

TEST(Config, MinimalHasDefaults) {
  auto c = ParseConfig(kMinimal);
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c.value().backend, "gpiod");
  EXPECT_EQ(c.value().line(LineRole::kTrigger).offset, 4);
  EXPECT_TRUE(c.value().line(LineRole::kTrigger).active_low);
  EXPECT_FALSE(c.value().line(LineRole::kLaserA).active_low);
  EXPECT_EQ(c.value().max_message_bytes, 4096u);
  EXPECT_DOUBLE_EQ(c.value().timings.max_laser_on_ms, 1000.0);
}

TEST(Config, ShippedExamplesAreValid) {
  for (const char* name : {"sequencer.json", "sequencer-sim.json"}) {
    auto c = LoadConfig(SourceDir() + "/examples/sequencer/" + name);
    EXPECT_TRUE(c.ok()) << name << ": " << c.status().ToString();
  }
  auto c = LoadConfig(SourceDir() + "/examples/sequencer/sequencer.json");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c.value().line(LineRole::kLaserB).offset, 27);
  EXPECT_DOUBLE_EQ(c.value().timings.blocker_settle_ms, 80.0);
}

struct Bad {
  const char* json;
  const char* expected_in_message;
};

class ConfigRejects : public ::testing::TestWithParam<Bad> {};

TEST_P(ConfigRejects, NamesTheProblem) {
  auto c = ParseConfig(GetParam().json);
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(c.status().message().find(GetParam().expected_in_message), std::string::npos) << c.status().message();
}

INSTANTIATE_TEST_SUITE_P(
    Sequencer, ConfigRejects,
    ::testing::Values(
        Bad{"{", "configuration"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}}})", "lines.trigger: missing"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 1}, "blocker": {"offset": 3}, "trigger": {"offset": 4}}})",
            "lines.laser_b.offset = 1: same line as lines.laser_a"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}},
               "timings_ms": {"max_lasr_on": 5}})", "timings_ms.max_lasr_on: unknown key"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}},
               "timings_ms": {"laser_warmup": 50, "exposure": 30, "blocker_settle": 10, "max_laser_on": 80}})",
            "timings_ms.max_laser_on = 80: must exceed a frame's laser-on time max(laser_warmup, blocker_settle) + exposure = 80 ms"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}},
               "timings_ms": {"trigger_pulse": 5, "exposure": 2}})", "timings_ms.exposure = 2: must be >= trigger_pulse (5 ms)"},
        Bad{R"({"lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": -4}}})",
            "lines.trigger.offset = -4"},
        Bad{R"({"lines": {"laser_a": {"offset": "1"}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}}})",
            "lines.laser_a.offset: must be an integer"},
        Bad{R"({"gpio": {"backend": "spi"}, "lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}}})",
            "gpio.backend = 'spi'"},
        Bad{R"({"max_message_bytes": 10, "lines": {"laser_a": {"offset": 1}, "laser_b": {"offset": 2}, "blocker": {"offset": 3}, "trigger": {"offset": 4}}})",
            "max_message_bytes = 10"}));

TEST(Config, MissingFileIsNotFound) {
  auto c = LoadConfig("/nonexistent/opl/sequencer.json");
  EXPECT_EQ(c.status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace opl::sequencer
