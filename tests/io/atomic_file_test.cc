#include "opl/io/atomic_file.h"

#include <sys/stat.h>

#include <algorithm>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"

namespace opl {
namespace {

using testing_support::ReadAll;
using testing_support::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

TEST(WriteFileAtomically, WritesExactlyTheContentsAndLeavesNoTempFile) {
  TempDir dir;
  std::string contents("a,b\n1,2\n");
  contents += std::string("\0binary\xff", 8);
  ASSERT_TRUE(WriteFileAtomically(dir.File("out.csv"), contents).ok());
  EXPECT_EQ(ReadAll(dir.File("out.csv")), contents);
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"out.csv"});
}

TEST(WriteFileAtomically, ReplacesAnExistingFileKeepingItsMode) {
  TempDir dir;
  const std::string path = dir.Write("out.txt", "old contents that are longer\n");
  ASSERT_EQ(::chmod(path.c_str(), 0640), 0);
  ASSERT_TRUE(WriteFileAtomically(path, "new\n").ok());
  EXPECT_EQ(ReadAll(path), "new\n");
  struct stat st;
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"out.txt"});
}

TEST(WriteFileAtomically, NewFileGetsTheUmaskMode) {
  TempDir dir;
  const mode_t old_mask = ::umask(022);
  const Status st = WriteFileAtomically(dir.File("f"), "x");
  ::umask(old_mask);
  ASSERT_TRUE(st.ok());
  struct stat s;
  ASSERT_EQ(::stat(dir.File("f").c_str(), &s), 0);
  EXPECT_EQ(s.st_mode & 0777, 0644u);
}

TEST(WriteFileAtomically, MissingDirectoryFailsAndWritesNothing) {
  TempDir dir;
  const std::string path = dir.File("no_such_dir/out.csv");
  const Status st = WriteFileAtomically(path, "x");
  EXPECT_EQ(st.code(), StatusCode::kIoError);
  EXPECT_THAT(st.message(), StartsWith(path + ": cannot write: "));
  EXPECT_THAT(st.message(), HasSubstr("No such file or directory"));
  EXPECT_TRUE(dir.Entries().empty());
}

// The temporary file is created and written, then rename fails (EISDIR): the
// temporary file must be removed.
TEST(WriteFileAtomically, FailedRenameRemovesTheTempFile) {
  TempDir dir;
  ASSERT_EQ(::mkdir(dir.File("sub").c_str(), 0755), 0);
  const Status st = WriteFileAtomically(dir.File("sub"), "x");
  EXPECT_EQ(st.code(), StatusCode::kIoError);
  EXPECT_THAT(st.message(), HasSubstr("rename failed: Is a directory"));
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"sub"});
}

TEST(WriteFileAtomically, PathThroughARegularFileFails) {
  TempDir dir;
  const std::string file = dir.Write("plain", "keep\n");
  const Status st = WriteFileAtomically(file + "/child", "x");
  EXPECT_EQ(st.code(), StatusCode::kIoError);
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"plain"});
  EXPECT_EQ(ReadAll(file), "keep\n");
}

TEST(WriteFileAtomically, ManyWritesLeaveOnlyTheTarget) {
  TempDir dir;
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(WriteFileAtomically(dir.File("f"), std::to_string(i)).ok());
  }
  EXPECT_EQ(ReadAll(dir.File("f")), "19");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"f"});
}

TEST(ReadFileToString, ReadsAndReportsMissingFiles) {
  TempDir dir;
  const std::string path = dir.Write("a", "hello");
  Result<std::string> text = ReadFileToString(path);
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(*text, "hello");
  Result<std::string> missing = ReadFileToString(dir.File("b"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_EQ(missing.status().message(),
            dir.File("b") + ": cannot open: No such file or directory");
  Result<std::string> directory = ReadFileToString(dir.path());
  ASSERT_FALSE(directory.ok());
  EXPECT_THAT(directory.status().message(), HasSubstr("is a directory"));
}

TEST(ReadFileToString, OnlyRegularFilesOfBoundedSize) {
  // Issue 19: /dev/zero as an input read forever.
  for (const char* device : {"/dev/zero", "/dev/urandom"}) {
    Result<std::string> text = ReadFileToString(device);
    ASSERT_FALSE(text.ok());
    EXPECT_EQ(text.status().code(), StatusCode::kIoError);
    EXPECT_EQ(text.status().message(),
              std::string(device) + ": cannot read: not a regular file (a device, FIFO or socket)");
  }
  TempDir dir;
  const std::string path = dir.Write("big", std::string(1001, 'x'));
  EXPECT_EQ(ReadFileToString(path, 1000).status().message(),
            path + ": cannot read: 1001 bytes, more than the 1000 an input may have");
  EXPECT_EQ(ReadFileToString(path, 1001)->size(), 1001u);
  EXPECT_EQ(kMaxInputFileBytes, 536870912);
}

TEST(AtomicFileWriter, StreamsBlocksAndAppearsOnlyOnCommit) {
  TempDir dir;
  const std::string path = dir.Write("out.bin", "old");
  AtomicFileWriter writer;
  ASSERT_TRUE(writer.Open(path).ok());
  EXPECT_TRUE(writer.is_open());
  for (int i = 0; i < 3; ++i) {
    const std::string block(1000, static_cast<char>('a' + i));
    ASSERT_TRUE(writer.Write(block.data(), block.size()).ok());
  }
  EXPECT_EQ(writer.bytes_written(), 3000);
  EXPECT_EQ(ReadAll(path), "old");  // untouched until Commit
  EXPECT_EQ(dir.Entries().size(), 2u);  // out.bin and the temporary file
  ASSERT_TRUE(writer.Commit().ok());
  EXPECT_EQ(ReadAll(path), std::string(1000, 'a') + std::string(1000, 'b') + std::string(1000, 'c'));
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"out.bin"});
  EXPECT_FALSE(writer.is_open());
  EXPECT_THAT(writer.Write("x", 1).message(), HasSubstr("the writer is not open"));
}

TEST(AtomicFileWriter, AbandonAndDestructorLeaveNothing) {
  TempDir dir;
  {
    AtomicFileWriter writer;
    ASSERT_TRUE(writer.Open(dir.File("a.ply")).ok());
    ASSERT_TRUE(writer.Write("partial", 7).ok());
    writer.Abandon();
    EXPECT_EQ(writer.temp_path(), "");
  }
  {
    AtomicFileWriter writer;
    ASSERT_TRUE(writer.Open(dir.File("b.ply")).ok());
    ASSERT_TRUE(writer.Write("partial", 7).ok());
  }  // destroyed without Commit
  EXPECT_TRUE(dir.Entries().empty());
  AtomicFileWriter writer;
  EXPECT_THAT(writer.Open(dir.File("missing/c.ply")).message(),
              StartsWith(dir.File("missing/c.ply") + ": cannot write: cannot create a temporary file"));
}

}  // namespace
}  // namespace opl
