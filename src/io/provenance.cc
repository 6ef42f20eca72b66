#include "opl/io/provenance.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <set>
#include <system_error>

#include <nlohmann/json.hpp>
#include <openssl/evp.h>

#include "opl/core/version.h"

namespace opl {
namespace {

struct MdContextDeleter {
  void operator()(EVP_MD_CTX* ctx) const { EVP_MD_CTX_free(ctx); }
};
using MdContext = std::unique_ptr<EVP_MD_CTX, MdContextDeleter>;

std::string Hex(const unsigned char* digest, unsigned int length) {
  static const char kDigits[] = "0123456789abcdef";
  std::string hex(2 * length, '0');
  for (unsigned int i = 0; i < length; ++i) {
    hex[2 * i] = kDigits[digest[i] >> 4];
    hex[2 * i + 1] = kDigits[digest[i] & 0xf];
  }
  return hex;
}

std::string OneLine(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  return out;
}

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

}  // namespace

std::string Sha256Hex(std::string_view bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  MdContext ctx(EVP_MD_CTX_new());
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1 ||
      EVP_DigestUpdate(ctx.get(), bytes.data(), bytes.size()) != 1 ||
      EVP_DigestFinal_ex(ctx.get(), digest, &length) != 1) {
    return std::string();
  }
  return Hex(digest, length);
}

Result<InputDigest> DigestFile(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) return Status::IoError(path + ": cannot open: " + std::strerror(errno));
  MdContext ctx(EVP_MD_CTX_new());
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1) {
    return Status::IoError(path + ": SHA-256: cannot initialise libcrypto's digest");
  }
  InputDigest digest;
  digest.path = path;
  std::vector<char> block(1 << 20);
  for (;;) {
    const size_t n = std::fread(block.data(), 1, block.size(), file.get());
    if (n > 0) {
      EVP_DigestUpdate(ctx.get(), block.data(), n);
      digest.bytes += n;
    }
    if (n < block.size()) {
      if (std::ferror(file.get())) {
        return Status::IoError(path + ": cannot read: " + std::strerror(errno));
      }
      break;
    }
  }
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_DigestFinal_ex(ctx.get(), md, &length) != 1) {
    return Status::IoError(path + ": SHA-256: libcrypto's digest failed");
  }
  digest.sha256_hex = Hex(md, length);
  return digest;
}

Result<Provenance> MakeProvenance(const std::string& tool, int argc, const char* const* argv,
                                  const std::vector<std::string>& input_paths) {
  Provenance p;
  p.tool = tool;
  p.version = VersionString();
  p.time_utc = UtcNow();
  for (int i = 0; i < argc; ++i) p.command_line.push_back(i == 0 ? tool : std::string(argv[i]));
  std::set<std::string> seen;
  for (const std::string& path : input_paths) {
    if (path.empty() || !seen.insert(path).second) continue;
    Result<InputDigest> d = DigestFile(path);
    if (!d.ok()) return d.status();
    p.inputs.push_back(*d);
  }
  return p;
}

std::string FormatProvenanceJson(const Provenance& provenance) {
  nlohmann::ordered_json j;
  j["tool"] = provenance.tool;
  j["version"] = provenance.version;
  j["time_utc"] = provenance.time_utc;
  j["command_line"] = provenance.command_line;
  j["inputs"] = nlohmann::ordered_json::array();
  for (const InputDigest& d : provenance.inputs) {
    j["inputs"].push_back({{"path", d.path}, {"bytes", d.bytes}, {"sha256", d.sha256_hex}});
  }
  // Invalid UTF-8 in a path or argument is replaced, never a throw.
  return j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

std::string FormatProvenanceComment(const Provenance& provenance, const std::string& prefix) {
  std::string text;
  const auto line = [&](const std::string& field, const std::string& value) {
    text += prefix + "opl " + field + ": " + OneLine(value) + "\n";
  };
  line("tool", provenance.tool);
  line("version", provenance.version);
  line("time_utc", provenance.time_utc);
  std::string command;
  for (const std::string& arg : provenance.command_line) command += (command.empty() ? "" : " ") + arg;
  line("command_line", command);
  for (const InputDigest& d : provenance.inputs) {
    line("input", d.path + " " + std::to_string(d.bytes) + " bytes sha256 " + d.sha256_hex);
  }
  return text;
}

}  // namespace opl
