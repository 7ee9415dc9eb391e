#include "core/image/image_codec.h"

#include <algorithm>
#include <csetjmp>
#include <cstdio>  // Before jpeglib.h, which uses FILE.
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include <jerror.h>
#include <jpeglib.h>
#include <png.h>

namespace visloc::image {
namespace {

std::string HexPrefix(const void* data, size_t size) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  std::string hex;
  for (size_t i = 0; i < std::min<size_t>(size, 4); ++i) {
    char byte[4];
    std::snprintf(byte, sizeof(byte), i ? " %02x" : "%02x", bytes[i]);
    hex += byte;
  }
  return hex;
}

std::string SizeError(int64_t width, int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height) + " pixels, more than the " +
         std::to_string(kMaxDecodedPixels) + " decoded at most";
}

// libpng and libjpeg report errors by longjmp. Everything the error path needs (the message,
// the buffers to free, the image being filled) lives in these states, outside the frame that
// called setjmp: locals changed after setjmp are indeterminate once longjmp returns there.

struct PngReadState {
  const uint8_t* data = nullptr;
  size_t size = 0;
  size_t offset = 0;
  std::string error;
  std::vector<png_bytep> rows;
};

void PngError(png_structp png, png_const_charp message) {
  static_cast<std::string*>(png_get_error_ptr(png))->assign(message);
  png_longjmp(png, 1);
}

void PngWarning(png_structp, png_const_charp) {}  // Ancillary-chunk complaints: not the pixels.

void PngReadFromMemory(png_structp png, png_bytep out, png_size_t length) {
  auto* state = static_cast<PngReadState*>(png_get_io_ptr(png));
  if (length > state->size - state->offset) png_error(png, "truncated PNG: the data ends early");
  std::memcpy(out, state->data + state->offset, length);
  state->offset += length;
}

// The transformations cv::imdecode(..., IMREAD_GRAYSCALE) asks libpng for, in its order.
bool RunPngDecode(png_structp png, png_infop info, PngReadState* state, cv::Mat* grey) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_read_fn(png, state, &PngReadFromMemory);
  png_read_info(png, info);
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0;
  png_get_IHDR(png, info, &width, &height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
  if (int64_t{width} * height > kMaxDecodedPixels) {
    state->error = "PNG of " + SizeError(width, height);
    return false;
  }
  if (bit_depth == 16) png_set_strip_16(png);
  png_set_strip_alpha(png);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if ((color_type & PNG_COLOR_MASK_COLOR) == 0 && bit_depth < 8) {
    png_set_expand_gray_1_2_4_to_8(png);
  }
  png_set_rgb_to_gray(png, 1, 0.299, 0.587);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  grey->create(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  state->rows.resize(height);
  for (png_uint_32 y = 0; y < height; ++y) state->rows[y] = grey->ptr<uint8_t>(y);
  png_read_image(png, state->rows.data());
  png_read_end(png, nullptr);
  return true;
}

cv::Mat DecodePng(const uint8_t* data, size_t size, std::string* error) {
  PngReadState state;
  state.data = data;
  state.size = size;
  png_structp png =
      png_create_read_struct(PNG_LIBPNG_VER_STRING, &state.error, &PngError, &PngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  cv::Mat grey;
  const bool ok = info && RunPngDecode(png, info, &state, &grey);
  png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
  if (ok) return grey;
  *error = state.error.empty() ? "corrupt PNG" : state.error;
  if (error->find("PNG") == std::string::npos) *error = "corrupt PNG: " + *error;
  return cv::Mat();
}

// Reached from libjpeg's callbacks through cinfo->client_data.
struct JpegErrorState {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  std::string error;
  bool data_ended_early = false;
};

void JpegErrorExit(j_common_ptr cinfo) {
  auto* state = static_cast<JpegErrorState*>(cinfo->client_data);
  char message[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, message);
  state->error = message;
  std::longjmp(state->jump, 1);
}

// Warnings (level -1) decode on; the one that means the data ended early is kept, to refuse
// the image: libjpeg fills the missing rows with grey.
void JpegMessage(j_common_ptr cinfo, int level) {
  if (level == -1 && cinfo->err->msg_code == JWRN_JPEG_EOF) {
    static_cast<JpegErrorState*>(cinfo->client_data)->data_ended_early = true;
  }
}

// libjpeg's error manager on `errors`, set before jpeg_create_(de)compress, which keeps
// client_data.
template <typename Cinfo>
void AttachErrors(Cinfo* cinfo, JpegErrorState* errors) {
  cinfo->err = jpeg_std_error(&errors->manager);
  errors->manager.error_exit = &JpegErrorExit;
  errors->manager.emit_message = &JpegMessage;
  cinfo->client_data = errors;
}

struct JpegReadState {
  jpeg_decompress_struct cinfo;
  JpegErrorState errors;
};

bool RunJpegDecode(const uint8_t* data, size_t size, JpegReadState* state, cv::Mat* grey) {
  if (setjmp(state->errors.jump)) return false;
  jpeg_mem_src(&state->cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&state->cinfo, TRUE);
  if (state->cinfo.num_components == 4) {
    state->errors.error = "CMYK JPEG: only grey and colour (YCbCr) JPEGs are read";
    return false;
  }
  state->cinfo.out_color_space = JCS_GRAYSCALE;
  jpeg_start_decompress(&state->cinfo);
  const int64_t width = state->cinfo.output_width, height = state->cinfo.output_height;
  if (width * height > kMaxDecodedPixels) {
    state->errors.error = "JPEG of " + SizeError(width, height);
    return false;
  }
  grey->create(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  while (state->cinfo.output_scanline < state->cinfo.output_height) {
    JSAMPROW row = grey->ptr<uint8_t>(static_cast<int>(state->cinfo.output_scanline));
    jpeg_read_scanlines(&state->cinfo, &row, 1);
  }
  jpeg_finish_decompress(&state->cinfo);
  if (state->errors.data_ended_early) {
    state->errors.error = "truncated JPEG: the data ends before the image does";
    return false;
  }
  return true;
}

cv::Mat DecodeJpeg(const uint8_t* data, size_t size, std::string* error) {
  JpegReadState state;
  AttachErrors(&state.cinfo, &state.errors);
  jpeg_create_decompress(&state.cinfo);
  cv::Mat grey;
  const bool ok = RunJpegDecode(data, size, &state, &grey);
  jpeg_destroy_decompress(&state.cinfo);
  if (ok) return grey;
  *error = state.errors.error;
  if (error->find("JPEG") == std::string::npos) *error = "corrupt JPEG: " + *error;
  return cv::Mat();
}

bool CheckEncodable(const cv::Mat& image, std::initializer_list<int> channels, std::string* error) {
  if (image.empty()) {
    *error = "an empty image";
  } else if (image.depth() != CV_8U) {
    *error = "not an 8-bit image";
  } else if (std::find(channels.begin(), channels.end(), image.channels()) == channels.end()) {
    *error = "an image of " + std::to_string(image.channels()) + " channels";
  } else {
    return true;
  }
  return false;
}

struct PngWriteState {
  std::vector<uint8_t>* out = nullptr;
  std::string error;
  std::vector<png_bytep> rows;
};

void PngWriteToMemory(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<PngWriteState*>(png_get_io_ptr(png))->out;
  out->insert(out->end(), data, data + length);
}

// cv::imencode's settings when given IMWRITE_PNG_COMPRESSION: the level, zlib's default
// strategy, libpng's default filters.
bool RunPngEncode(png_structp png, png_infop info, const cv::Mat& image, int level,
                  PngWriteState* state) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_write_fn(png, state, &PngWriteToMemory, nullptr);
  png_set_compression_level(png, level);
  png_set_compression_strategy(png, 0);  // Z_DEFAULT_STRATEGY.
  const int type = image.channels() == 1   ? PNG_COLOR_TYPE_GRAY
                   : image.channels() == 3 ? PNG_COLOR_TYPE_RGB
                                           : PNG_COLOR_TYPE_RGB_ALPHA;
  png_set_IHDR(png, info, image.cols, image.rows, 8, type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_set_bgr(png);
  state->rows.resize(image.rows);
  for (int y = 0; y < image.rows; ++y) state->rows[y] = const_cast<uint8_t*>(image.ptr(y));
  png_write_image(png, state->rows.data());
  png_write_end(png, info);
  return true;
}

struct JpegWriteState {
  jpeg_compress_struct cinfo;
  JpegErrorState errors;
  unsigned char* buffer = nullptr;  // jpeg_mem_dest's, malloc'd: freed by us.
  unsigned long buffer_size = 0;
};

bool RunJpegEncode(const cv::Mat& image, int quality, JpegWriteState* state) {
  if (setjmp(state->errors.jump)) return false;
  jpeg_compress_struct& cinfo = state->cinfo;
  jpeg_mem_dest(&cinfo, &state->buffer, &state->buffer_size);
  cinfo.image_width = static_cast<JDIMENSION>(image.cols);
  cinfo.image_height = static_cast<JDIMENSION>(image.rows);
  cinfo.input_components = image.channels();
  cinfo.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<uint8_t*>(image.ptr(static_cast<int>(cinfo.next_scanline)));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  return true;
}

}  // namespace

Format SniffFormat(const void* data, size_t size) {
  static constexpr uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const auto* bytes = static_cast<const uint8_t*>(data);
  if (size >= 8 && std::memcmp(bytes, kPngSignature, 8) == 0) return Format::kPng;
  if (size >= 3 && bytes[0] == 0xff && bytes[1] == 0xd8 && bytes[2] == 0xff) return Format::kJpeg;
  return Format::kUnknown;
}

cv::Mat DecodeGrey(const void* data, size_t size, std::string* error) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  switch (SniffFormat(data, size)) {
    case Format::kPng:
      return DecodePng(bytes, size, error);
    case Format::kJpeg:
      return DecodeJpeg(bytes, size, error);
    case Format::kUnknown:
      break;
  }
  *error = size == 0 ? "no image data (0 bytes)"
                     : "not a PNG or JPEG image (first bytes " + HexPrefix(data, size) + ")";
  return cv::Mat();
}

cv::Mat ReadGrey(const std::string& path, std::string* error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    *error = path + ": cannot open";
    return cv::Mat();
  }
  std::ostringstream bytes;  // One read of the whole file (not character by character).
  bytes << file.rdbuf();
  if (file.bad()) {
    *error = path + ": cannot read";
    return cv::Mat();
  }
  const std::string data = bytes.str();
  cv::Mat grey = DecodeGrey(data.data(), data.size(), error);
  if (grey.empty()) *error = path + ": " + *error;
  return grey;
}

bool EncodePng(const cv::Mat& image, int compression_level, std::vector<uint8_t>* png,
               std::string* error) {
  if (!CheckEncodable(image, {1, 3, 4}, error)) {
    *error = "cannot encode " + *error + " as PNG";
    return false;
  }
  PngWriteState state;
  state.out = png;
  png->clear();
  png_structp writer =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, &state.error, &PngError, &PngWarning);
  png_infop info = writer ? png_create_info_struct(writer) : nullptr;
  const bool ok =
      info && RunPngEncode(writer, info, image, std::clamp(compression_level, 0, 9), &state);
  png_destroy_write_struct(&writer, info ? &info : nullptr);
  if (!ok) *error = "PNG encoding failed: " + state.error;
  return ok;
}

bool EncodeJpeg(const cv::Mat& image, int quality, std::vector<uint8_t>* jpeg, std::string* error) {
  if (!CheckEncodable(image, {1, 3}, error)) {
    *error = "cannot encode " + *error + " as JPEG";
    return false;
  }
  JpegWriteState state;
  AttachErrors(&state.cinfo, &state.errors);
  jpeg_create_compress(&state.cinfo);
  const bool ok = RunJpegEncode(image, std::clamp(quality, 1, 100), &state);
  jpeg_destroy_compress(&state.cinfo);
  if (ok) jpeg->assign(state.buffer, state.buffer + state.buffer_size);
  std::free(state.buffer);
  if (!ok) *error = "JPEG encoding failed: " + state.errors.error;
  return ok;
}

bool WritePng(const std::string& path, const cv::Mat& image, int compression_level,
              std::string* error) {
  std::vector<uint8_t> png;
  if (!EncodePng(image, compression_level, &png, error)) {
    *error = path + ": " + *error;
    return false;
  }
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  file.close();
  if (!file) {
    *error = path + ": cannot write the PNG";
    return false;
  }
  return true;
}

}  // namespace visloc::image
