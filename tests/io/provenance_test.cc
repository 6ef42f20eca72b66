// Provenance of outputs (io/provenance.h): SHA-256 against the FIPS 180-2
// test vectors and against coreutils' sha256sum, the JSON object and the
// comment block.
#include "opl/io/provenance.h"

#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/temp_dir.h"
#include "opl/core/version.h"

namespace opl {
namespace {

using testing_support::TempDir;

TEST(Sha256, FipsTestVectors) {
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

// A file of 3 MiB + 17 bytes (several 1 MiB blocks and a partial one) hashes
// as the same bytes in memory and as coreutils' sha256sum says.
TEST(Sha256, FileDigestMatchesSha256sum) {
  TempDir dir;
  std::string bytes((3u << 20) + 17u, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 2654435761u) >> 13);
  const std::string path = dir.Write("data.bin", bytes);
  Result<InputDigest> d = DigestFile(path);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ(d->bytes, bytes.size());
  EXPECT_EQ(d->sha256_hex, Sha256Hex(bytes));
  std::FILE* pipe = popen(("sha256sum '" + path + "'").c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  char line[256] = {0};
  ASSERT_NE(std::fgets(line, sizeof line, pipe), nullptr);
  pclose(pipe);
  EXPECT_EQ(std::string(line).substr(0, 64), d->sha256_hex);
}

TEST(Sha256, UnreadableFilesAreIoErrorsNamingThePath) {
  TempDir dir;
  Result<InputDigest> missing = DigestFile(dir.File("nope.json"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kIoError);
  EXPECT_EQ(missing.status().message(), dir.File("nope.json") + ": cannot open: No such file or directory");
  Result<InputDigest> directory = DigestFile(dir.path());
  ASSERT_FALSE(directory.ok());
  EXPECT_EQ(directory.status().message(), dir.path() + ": cannot read: Is a directory");
}

TEST(Provenance, RecordsToolVersionTimeCommandLineAndInputs) {
  TempDir dir;
  const std::string cal = dir.Write("cal.json", "{}");
  const std::string spots = dir.Write("spots.csv", "x,y,z\n");
  const char* argv[] = {"/usr/local/bin/opl_measure", "--calibration", cal.c_str(), "--spots",
                        spots.c_str()};
  Result<Provenance> p = MakeProvenance("opl_measure", 5, argv, {cal, "", spots, cal});
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_EQ(p->tool, "opl_measure");
  EXPECT_EQ(p->version, VersionString());
  // "20YY-MM-DDThh:mm:ssZ": digits where the shape has 'd', the rest as is.
  const std::string shape = "20dd-dd-ddTdd:dd:ddZ";
  bool iso = p->time_utc.size() == shape.size();
  for (size_t k = 0; iso && k < shape.size(); ++k) {
    const char c = p->time_utc[k];
    iso = shape[k] == 'd' ? (c >= '0' && c <= '9') : c == shape[k];
  }
  EXPECT_TRUE(iso) << p->time_utc;
  ASSERT_EQ(p->command_line.size(), 5u);
  EXPECT_EQ(p->command_line[0], "opl_measure");  // not the install path
  EXPECT_EQ(p->command_line[2], cal);
  ASSERT_EQ(p->inputs.size(), 2u);  // the empty path skipped, cal.json hashed once
  EXPECT_EQ(p->inputs[0].path, cal);
  EXPECT_EQ(p->inputs[0].bytes, 2u);
  EXPECT_EQ(p->inputs[0].sha256_hex, Sha256Hex("{}"));
  EXPECT_EQ(p->inputs[1].sha256_hex, Sha256Hex("x,y,z\n"));

  const nlohmann::json j = nlohmann::json::parse(FormatProvenanceJson(*p));
  EXPECT_EQ(j.at("tool"), "opl_measure");
  EXPECT_EQ(j.at("version"), VersionString());
  EXPECT_EQ(j.at("time_utc"), p->time_utc);
  EXPECT_EQ(j.at("command_line").size(), 5u);
  EXPECT_EQ(j.at("inputs").at(1).at("sha256"), Sha256Hex("x,y,z\n"));
  EXPECT_EQ(j.at("inputs").at(0).at("bytes"), 2);

  const std::string comment = FormatProvenanceComment(*p, "# ");
  EXPECT_EQ(comment.substr(0, 23), "# opl tool: opl_measure");
  EXPECT_NE(comment.find("# opl input: " + spots + " 6 bytes sha256 " + Sha256Hex("x,y,z\n") + "\n"),
            std::string::npos);
}

// An argument with a newline or invalid UTF-8 stays one comment line and
// valid JSON.
TEST(Provenance, HostileArgumentsStayOneLineAndValidJson) {
  const char* argv[] = {"opl_measure", "--apply", "a\nb.csv", "\xff\xfe"};
  Result<Provenance> p = MakeProvenance("opl_measure", 4, argv, {});
  ASSERT_TRUE(p.ok());
  const std::string comment = FormatProvenanceComment(*p, "# ");
  size_t lines = 0;
  for (char c : comment) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, 4u);  // tool, version, time, command line
  EXPECT_NE(comment.find("--apply a?b.csv"), std::string::npos);
  EXPECT_NO_THROW(nlohmann::json::parse(FormatProvenanceJson(*p)));
}

}  // namespace
}  // namespace opl
