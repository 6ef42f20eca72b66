// All of a run's outputs or none (io/output_set.h): staged files appear
// together at Commit(), a failure while staging or committing leaves every
// path as it was, and a stamped set writes each file's provenance.
#include "opl/io/output_set.h"

#include <sys/stat.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "io/temp_dir.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;

Provenance TestProvenance() {
  Provenance p;
  p.tool = "opl_test";
  p.version = "9.9.9 (commit 0123456789ab)";
  p.time_utc = "2026-12-02T10:00:00Z";
  p.command_line = {"opl_test", "--out", "x.json"};
  p.inputs = {{"in.csv", 12, std::string(64, 'a')}};
  return p;
}

TEST(OutputSet, NothingAppearsBeforeCommitThenEverything) {
  TempDir dir;
  OutputSet out;
  ASSERT_TRUE(out.Add(dir.File("a.txt"), "alpha\n").ok());
  ASSERT_TRUE(out.Add(dir.File("b.csv"), "x,y\n1,2\n").ok());
  EXPECT_FALSE(std::filesystem::exists(dir.File("a.txt")));
  EXPECT_FALSE(std::filesystem::exists(dir.File("b.csv")));
  ASSERT_TRUE(out.Commit().ok());
  EXPECT_EQ(ReadAll(dir.File("a.txt")), "alpha\n");
  EXPECT_EQ(ReadAll(dir.File("b.csv")), "x,y\n1,2\n");
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"a.txt", "b.csv"}));  // no temp, no backup
}

// The second output's folder does not exist: staging fails, the set is
// dropped, and the first path keeps its old contents (no temporary left).
TEST(OutputSet, FailureWhileStagingLeavesEveryPathAsItWas) {
  TempDir dir;
  dir.Write("a.txt", "old\n");
  {
    OutputSet out;
    ASSERT_TRUE(out.Add(dir.File("a.txt"), "new\n").ok());
    const Status st = out.Add(dir.File("missing/b.txt"), "b\n");
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.message().find("missing/b.txt: cannot write"), std::string::npos) << st.message();
  }
  EXPECT_EQ(ReadAll(dir.File("a.txt")), "old\n");
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"a.txt"}));
}

// A rename that fails in the middle of Commit (the third file's temporary
// removed behind the set's back): the files already replaced get their old
// contents back, a file that did not exist is removed, nothing else is left.
TEST(OutputSet, FailureWhileCommittingRestoresTheReplacedFiles) {
  TempDir dir;
  dir.Write("a.txt", "old a\n");
  OutputSet out;
  ASSERT_TRUE(out.Add(dir.File("a.txt"), "new a\n").ok());
  ASSERT_TRUE(out.Add(dir.File("b.txt"), "new b\n").ok());
  ASSERT_TRUE(out.Add(dir.File("c.txt"), "new c\n").ok());
  int removed = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    if (e.path().filename().string().rfind(".c.txt.tmp-", 0) == 0) {
      std::filesystem::remove(e.path());
      ++removed;
    }
  }
  ASSERT_EQ(removed, 1);
  const Status st = out.Commit();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("c.txt: cannot write: rename failed"), std::string::npos)
      << st.message();
  EXPECT_EQ(ReadAll(dir.File("a.txt")), "old a\n");
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"a.txt"}));
}

TEST(OutputSet, RefusesAPathTwiceAndAFolder) {
  TempDir dir;
  std::filesystem::create_directory(dir.File("folder.json"));
  OutputSet out;
  ASSERT_TRUE(out.Add(dir.File("a.txt"), "a\n").ok());
  Status twice = out.Add(dir.File("a.txt"), "again\n");
  EXPECT_NE(twice.message().find("a.txt: cannot write: named twice"), std::string::npos)
      << twice.message();
  Status folder = out.Add(dir.File("folder.json"), "{}");
  EXPECT_NE(folder.message().find("folder.json: cannot write: is a directory"), std::string::npos)
      << folder.message();
}

TEST(OutputSet, StampsEveryFileWithTheProvenanceAndRefusesAnUnknownFormat) {
  TempDir dir;
  OutputSet out(TestProvenance());
  ASSERT_TRUE(out.Add(dir.File("r.json"), "{\n  \"s\": 1.5\n}\n").ok());
  ASSERT_TRUE(out.Add(dir.File("p.csv"), "x,y\n").ok());
  const Status unknown = out.Add(dir.File("r.bin"), "xx");
  EXPECT_EQ(unknown.message(), dir.File("r.bin") + ": no provenance format for '.bin' files");
  ASSERT_TRUE(out.AddVerbatim(dir.File("r.bin"), "xx").ok());
  ASSERT_TRUE(out.Commit().ok());
  const std::string json = ReadAll(dir.File("r.json"));
  EXPECT_EQ(json.rfind("{\n  \"s\": 1.5,\n  \"provenance\": {\"tool\":\"opl_test\"", 0), 0u) << json;
  EXPECT_EQ(ReadAll(dir.File("p.csv")).rfind("# opl tool: opl_test\n", 0), 0u);
  EXPECT_EQ(ReadAll(dir.File("r.bin")), "xx");
}

}  // namespace
}  // namespace opl
