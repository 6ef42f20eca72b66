#include "opl/vision/image_decode.h"

#include <algorithm>
#include <climits>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <new>
#include <utility>

#include <jpeglib.h>
#include <png.h>
#include <opencv2/imgcodecs.hpp>

#include "opl/core/message_text.h"

// libpng and libjpeg report errors by calling a handler that must not
// return: ours longjmp back to a setjmp. A longjmp skips destructors, so every
// function that calls setjmp here (the *Phase functions) holds only trivially
// destructible objects, and the C++ objects (cv::Mat, vectors) live in their
// callers, which the longjmp never crosses. The handlers collect the
// libraries' messages into fixed buffers (MessageLog): nothing is allocated,
// and nothing is printed.

namespace opl {

namespace {

// libjpeg's messages are at most JMSG_LENGTH_MAX (200) bytes; libpng's are
// cut to this too.
constexpr size_t kMessageBytes = 200;

struct MessageLog {
  char error[kMessageBytes + 1];
  char warnings[kMaxDecodeWarnings][kMessageBytes + 1];
  int num_warnings;  // all of them, kept or not
};

void CopyMessage(char* to, const char* from) {
  std::snprintf(to, kMessageBytes + 1, "%s", from != nullptr ? from : "");
}

void AddWarning(MessageLog* log, const char* text) {
  if (log->num_warnings < kMaxDecodeWarnings) CopyMessage(log->warnings[log->num_warnings], text);
  if (log->num_warnings < INT_MAX) ++log->num_warnings;
}

std::vector<std::string> WarningsOf(const MessageLog& log) {
  std::vector<std::string> out;
  const int kept = std::min(log.num_warnings, kMaxDecodeWarnings);
  for (int i = 0; i < kept; ++i) out.push_back(SafeForMessage(log.warnings[i]));
  if (log.num_warnings > kept) {
    out.push_back("... " + std::to_string(log.num_warnings - kept) + " more warning(s)");
  }
  return out;
}

Status DecodeError(const std::string& name, const char* reason) {
  return Status::IoError(name + ": cannot decode the image: " +
                         SafeForMessage(*reason != '\0' ? reason : "unknown error"));
}

long long BigEndian(const unsigned char* p, int n) {
  long long v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

// ---------------------------------------------------------------- JPEG

struct JpegErrorManager {
  jpeg_error_mgr pub;  // first: libjpeg holds a jpeg_error_mgr*
  std::jmp_buf jump;
  MessageLog* log;
};

// Everything one decode needs; trivially destructible, zero-initialised.
struct JpegSession {
  jpeg_decompress_struct cinfo;
  JpegErrorManager error;
  jpeg_progress_mgr progress;
  MessageLog log;
};

[[noreturn]] void JpegErrorExit(j_common_ptr cinfo) {
  auto* manager = reinterpret_cast<JpegErrorManager*>(cinfo->err);
  char text[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, text);
  CopyMessage(manager->log->error, text);
  std::longjmp(manager->jump, 1);
}

// Level -1 is a warning (corrupt data the decoder works around); levels >= 0
// are trace messages, off at trace_level 0.
void JpegEmitMessage(j_common_ptr cinfo, int msg_level) {
  if (msg_level >= 0) return;
  auto* manager = reinterpret_cast<JpegErrorManager*>(cinfo->err);
  ++cinfo->err->num_warnings;
  char text[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, text);
  AddWarning(manager->log, text);
}

void JpegOutputMessage(j_common_ptr) {}  // never printed

// Called as scans are read: a progressive JPEG of many tiny scans costs a
// pass over the whole coefficient buffer per scan.
void JpegProgress(j_common_ptr cinfo) {
  if (!cinfo->is_decompressor) return;
  if (reinterpret_cast<j_decompress_ptr>(cinfo)->input_scan_number <= kMaxJpegScans) return;
  auto* manager = reinterpret_cast<JpegErrorManager*>(cinfo->err);
  std::snprintf(manager->log->error, kMessageBytes + 1, "more than %d scans", kMaxJpegScans);
  std::longjmp(manager->jump, 1);
}

void JpegInit(JpegSession* s) {
  s->cinfo.err = jpeg_std_error(&s->error.pub);
  s->error.pub.error_exit = JpegErrorExit;
  s->error.pub.emit_message = JpegEmitMessage;
  s->error.pub.output_message = JpegOutputMessage;
  s->error.log = &s->log;
  s->progress.progress_monitor = JpegProgress;
}

bool JpegHeaderPhase(JpegSession* s, const unsigned char* bytes, size_t size) {
  if (setjmp(s->error.jump) != 0) return false;
  jpeg_create_decompress(&s->cinfo);
  s->cinfo.progress = &s->progress;
  jpeg_mem_src(&s->cinfo, bytes, static_cast<unsigned long>(size));
  jpeg_read_header(&s->cinfo, TRUE);
  return true;
}

// OpenCV's CMYK to BGR (cv::imdecode's JPEG decoder), per pixel.
void CmykRowToBgr(const unsigned char* cmyk, unsigned char* bgr, unsigned width) {
  for (unsigned x = 0; x < width; ++x, cmyk += 4, bgr += 3) {
    const int k = cmyk[3];
    bgr[2] = static_cast<unsigned char>(k - ((255 - cmyk[0]) * k >> 8));
    bgr[1] = static_cast<unsigned char>(k - ((255 - cmyk[1]) * k >> 8));
    bgr[0] = static_cast<unsigned char>(k - ((255 - cmyk[2]) * k >> 8));
  }
}

// Decodes every row into `out` (rows `step` bytes apart); `cmyk_row` is a
// row of 4 * width bytes when the output colour space is CMYK.
bool JpegRowsPhase(JpegSession* s, unsigned char* out, size_t step, unsigned char* cmyk_row) {
  if (setjmp(s->error.jump) != 0) return false;
  jpeg_start_decompress(&s->cinfo);
  j_decompress_ptr cinfo = &s->cinfo;
  constexpr int kRowsPerCall = 16;
  JSAMPROW rows[kRowsPerCall];
  while (cinfo->output_scanline < cinfo->output_height) {
    const unsigned first = cinfo->output_scanline;
    JDIMENSION got = 0;
    if (cmyk_row != nullptr) {
      rows[0] = cmyk_row;
      got = jpeg_read_scanlines(cinfo, rows, 1);
      if (got == 1) CmykRowToBgr(cmyk_row, out + first * step, cinfo->output_width);
    } else {
      const unsigned n = std::min<unsigned>(kRowsPerCall, cinfo->output_height - first);
      for (unsigned i = 0; i < n; ++i) rows[i] = out + (first + i) * step;
      got = jpeg_read_scanlines(cinfo, rows, n);
    }
    if (got == 0) {  // a memory source never suspends; guard the loop anyway
      CopyMessage(s->log.error, "the decoder stopped before the last row");
      return false;
    }
  }
  return true;
}

bool JpegFinishPhase(JpegSession* s) {
  if (setjmp(s->error.jump) != 0) return false;
  jpeg_finish_decompress(&s->cinfo);
  return true;
}

// Owns the decompressor of a session; destroyed whatever the outcome.
struct JpegSessionGuard {
  JpegSession* s;
  ~JpegSessionGuard() { jpeg_destroy_decompress(&s->cinfo); }
};

Result<DecodedImage> DecodeJpeg(const unsigned char* bytes, size_t size, const std::string& name) {
  JpegSession s;
  std::memset(&s, 0, sizeof(s));
  JpegInit(&s);
  const JpegSessionGuard guard{&s};  // destroying a never-created decompressor is a no-op
  if (!JpegHeaderPhase(&s, bytes, size)) return DecodeError(name, s.log.error);
  j_decompress_ptr cinfo = &s.cinfo;
  OPL_RETURN_IF_ERROR(CheckImageSizeLimit(name, cinfo->image_width, cinfo->image_height));
  // As cv::imdecode with IMREAD_ANYCOLOR: one component is grey, four CMYK
  // (converted to BGR below), anything else BGR (libjpeg-turbo writes BGR
  // directly: the same values as RGB swapped).
  int channels = 3;
  if (cinfo->num_components == 1) {
    cinfo->out_color_space = JCS_GRAYSCALE;
    channels = 1;
  } else if (cinfo->num_components == 4) {
    cinfo->out_color_space = JCS_CMYK;
  } else {
    cinfo->out_color_space = JCS_EXT_BGR;
  }
  DecodedImage image;
  image.format = ImageFileFormat::kJpeg;
  image.pixels.create(static_cast<int>(cinfo->image_height), static_cast<int>(cinfo->image_width),
                      CV_8UC(channels));
  std::vector<unsigned char> cmyk_row(cinfo->num_components == 4 ? 4 * cinfo->image_width : 0);
  if (!JpegRowsPhase(&s, image.pixels.data, image.pixels.step,
                     cmyk_row.empty() ? nullptr : cmyk_row.data())) {
    return DecodeError(name, s.log.error);
  }
  // Every row is decoded: an error after the last scan (a damaged marker
  // before EOI) leaves the pixels whole, so it is a warning, as cv::imdecode
  // keeps such an image too.
  if (!JpegFinishPhase(&s)) {
    const std::string text = std::string("after the image data: ") + s.log.error;
    AddWarning(&s.log, text.c_str());
  }
  image.warnings = WarningsOf(s.log);
  return image;
}

// ---------------------------------------------------------------- PNG

struct PngSession {
  MessageLog log;
  std::jmp_buf jump;
  const unsigned char* bytes;
  size_t size;
  size_t at;
};

[[noreturn]] void PngError(png_structp png, png_const_charp message) {
  auto* s = static_cast<PngSession*>(png_get_error_ptr(png));
  CopyMessage(s->log.error, message);
  std::longjmp(s->jump, 1);
}

void PngWarning(png_structp png, png_const_charp message) {
  AddWarning(&static_cast<PngSession*>(png_get_error_ptr(png))->log, message);
}

void PngRead(png_structp png, png_bytep out, size_t length) {
  auto* s = static_cast<PngSession*>(png_get_io_ptr(png));
  if (length > s->size - s->at) png_error(png, "the file ends before the image does (truncated?)");
  std::memcpy(out, s->bytes + s->at, length);
  s->at += length;
}

bool PngInfoPhase(PngSession* s, png_structp png, png_infop info) {
  if (setjmp(s->jump) != 0) return false;
  png_set_read_fn(png, s, PngRead);
  png_set_user_limits(png, kMaxImageSidePx, kMaxImageSidePx);
  png_set_chunk_malloc_max(png, kMaxPngChunkBytes);
  // Every ancillary chunk but tRNS skipped (its CRC still checked): OpenCV
  // uses none of them, and libpng warns about some that are sound (an sRGB
  // profile it knows to be wrong).
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, nullptr, -1);
  png_read_info(png, info);
  return true;
}

// The transformations of cv::imdecode's PNG decoder for an output of
// `channels` (1 or 3) at the file's depth, then every row into `rows`.
bool PngRowsPhase(PngSession* s, png_structp png, png_infop info, int color_type, int bit_depth,
                  int channels, png_bytepp rows) {
  if (setjmp(s->jump) != 0) return false;
  png_set_swap(png);  // 16-bit samples: big-endian in the file, native in a cv::Mat
  png_set_strip_alpha(png);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if ((color_type & PNG_COLOR_MASK_COLOR) == 0 && bit_depth < 8) {
    png_set_expand_gray_1_2_4_to_8(png);
  }
  if (channels == 3) {
    if ((color_type & PNG_COLOR_MASK_COLOR) != 0) {
      png_set_bgr(png);
    } else {
      png_set_gray_to_rgb(png);  // grey + alpha
    }
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

// Walks the chunks before libpng does: a chunk whose length runs past the end
// of the file is refused (libpng would first allocate the length it claims:
// 2 GB for 0x7fffffff), and the size IHDR declares is checked against the
// limit. Anything else (a truncated chunk head) is left for libpng to judge.
Status CheckPngChunks(const unsigned char* bytes, size_t size, const std::string& name) {
  size_t at = 8;
  while (at + 12 <= size) {
    const unsigned long long length = static_cast<unsigned long long>(BigEndian(bytes + at, 4));
    const unsigned char* type = bytes + at + 4;
    if (length > size - at - 12) {
      return Status::IoError(
          name + ": cannot decode the image: PNG chunk " +
          QuoteForMessage(std::string(reinterpret_cast<const char*>(type), 4)) + " at byte " +
          std::to_string(at) + " claims " + std::to_string(length) + " bytes, more than the " +
          std::to_string(size - at - 12) + " left in the file");
    }
    if (at == 8 && length >= 8 && std::memcmp(type, "IHDR", 4) == 0) {
      OPL_RETURN_IF_ERROR(
          CheckImageSizeLimit(name, BigEndian(type + 4, 4), BigEndian(type + 8, 4)));
    }
    if (std::memcmp(type, "IEND", 4) == 0) break;
    at += 12 + length;
  }
  return Status::Ok();
}

struct PngGuard {
  png_structp png;
  png_infop info;
  ~PngGuard() { png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr); }
};

Result<DecodedImage> DecodePng(const unsigned char* bytes, size_t size, const std::string& name) {
  OPL_RETURN_IF_ERROR(CheckPngChunks(bytes, size, name));
  PngSession s;
  std::memset(&s, 0, sizeof(s));
  s.bytes = bytes;
  s.size = size;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &s, PngError, PngWarning);
  if (png == nullptr) return Status::IoError(name + ": cannot decode the image: out of memory");
  PngGuard guard{png, png_create_info_struct(png)};
  if (guard.info == nullptr) return Status::IoError(name + ": cannot decode the image: out of memory");
  if (!PngInfoPhase(&s, png, guard.info)) return DecodeError(name, s.log.error);
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0;
  png_get_IHDR(png, guard.info, &width, &height, &bit_depth, &color_type, nullptr, nullptr,
               nullptr);
  OPL_RETURN_IF_ERROR(CheckImageSizeLimit(name, width, height));
  // As cv::imdecode with IMREAD_ANYCOLOR: grey stays grey, every other colour
  // type (palette, RGB, grey + alpha, RGB + alpha) is BGR without alpha.
  const int channels = color_type == PNG_COLOR_TYPE_GRAY ? 1 : 3;
  DecodedImage image;
  image.format = ImageFileFormat::kPng;
  image.pixels.create(static_cast<int>(height), static_cast<int>(width),
                      CV_MAKETYPE(bit_depth == 16 ? CV_16U : CV_8U, channels));
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y) rows[y] = image.pixels.ptr(static_cast<int>(y));
  if (!PngRowsPhase(&s, png, guard.info, color_type, bit_depth, channels, rows.data())) {
    return DecodeError(name, s.log.error);
  }
  image.warnings = WarningsOf(s.log);
  return image;
}

// ---------------------------------------------------------------- others

Result<DecodedImage> DecodeWithOpenCv(const unsigned char* bytes, size_t size,
                                      const std::string& name) {
  DecodedImage image;
  if (size > 0) {
    const cv::Mat buffer(1, static_cast<int>(std::min<size_t>(size, INT_MAX)), CV_8UC1,
                         const_cast<unsigned char*>(bytes));
    image.pixels = cv::imdecode(buffer, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR |
                                            cv::IMREAD_IGNORE_ORIENTATION);
  }
  if (image.pixels.empty()) {
    return Status::IoError(name + ": cannot read the image (not an image file?)");
  }
  OPL_RETURN_IF_ERROR(CheckImageSizeLimit(name, image.pixels.cols, image.pixels.rows));
  return image;
}

}  // namespace

ImageFileFormat SniffImageFileFormat(const unsigned char* bytes, size_t size) {
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (size >= 8 && std::equal(kPng, kPng + 8, bytes)) return ImageFileFormat::kPng;
  if (size >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) {
    return ImageFileFormat::kJpeg;
  }
  return ImageFileFormat::kOther;
}

Status CheckImageSizeLimit(const std::string& name, long long width, long long height) {
  if (width <= kMaxImageSidePx && height <= kMaxImageSidePx &&
      width * height <= kMaxImagePixels) {
    return Status::Ok();
  }
  return Status::InvalidArgument(
      name + ": " + std::to_string(width) + " x " + std::to_string(height) +
      " pixels is beyond the limit of " + std::to_string(kMaxImageSidePx) + " pixels a side and " +
      std::to_string(kMaxImagePixels / 1000000) + " megapixels");
}

Result<DecodedImage> DecodeImage(const unsigned char* bytes, size_t size,
                                 const std::string& name) {
  try {
    switch (SniffImageFileFormat(bytes, size)) {
      case ImageFileFormat::kPng: return DecodePng(bytes, size, name);
      case ImageFileFormat::kJpeg: return DecodeJpeg(bytes, size, name);
      case ImageFileFormat::kOther: break;
    }
    return DecodeWithOpenCv(bytes, size, name);
  } catch (const cv::Exception& e) {
    std::string what = e.err.empty() ? std::string(e.what()) : e.err;
    return Status::IoError(name + ": cannot decode the image: " + SafeForMessage(what));
  } catch (const std::bad_alloc&) {
    return Status::IoError(name + ": cannot decode the image: out of memory");
  }
}

Result<std::vector<unsigned char>> ReadImageFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return Status::IoError(path + ": cannot read the image");
  const std::streamoff end = in.tellg();
  if (end < 0) return Status::IoError(path + ": cannot read the image");
  std::vector<unsigned char> bytes(static_cast<size_t>(end));
  in.seekg(0);
  if (!bytes.empty() &&
      !in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()))) {
    return Status::IoError(path + ": cannot read the image");
  }
  return bytes;
}

Result<DecodedImage> ReadImageFile(const std::string& path) {
  Result<std::vector<unsigned char>> bytes = ReadImageFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  return DecodeImage(bytes->data(), bytes->size(), path);
}

}  // namespace opl
