#pragma once
// PNG and JPEG, the image formats visloc takes (the product contract: "Images PNG or JPEG, grey
// or colour"), through libpng and libjpeg-turbo directly.
//
// Why not OpenCV's imgcodecs, which wraps the same two libraries: Debian builds it with GDAL,
// GDCM, OpenEXR and more, 141 shared libraries that every process linking it loads at start
// (0.1 s each time, 0.3 s under AddressSanitizer), and a robot's program linking the client
// library carried them all. Decoding here gives the pixels cv::imdecode(bytes,
// cv::IMREAD_GRAYSCALE) gives, bit for bit (the same libraries with the same transformations;
// image_codec_test.cc checks it on every real recording's images and on generated grey, colour,
// palette, 16-bit, interlaced PNGs and grey and colour JPEGs). Two deliberate differences: a
// truncated JPEG is an error here (OpenCV returns the rows it had, the rest grey), and a JPEG's
// EXIF orientation is not applied (a robot's camera writes none).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace visloc::image {

enum class Format { kUnknown, kPng, kJpeg };

// The format the first bytes announce (PNG's 8-byte signature, JPEG's SOI marker).
Format SniffFormat(const void* data, size_t size);

// Larger images are refused before their pixels are allocated (a corrupt or hostile header can
// claim any size): 2^27 pixels, 134 megapixels, several times any robot camera's.
constexpr int64_t kMaxDecodedPixels = int64_t{1} << 27;

// Decodes PNG or JPEG bytes to an 8-bit grey image: colour as cv::IMREAD_GRAYSCALE converts it
// (PNG: libpng's weights 0.299, 0.587 and 0.114; JPEG: the luma channel), alpha dropped, 16-bit
// samples to their high byte, palettes expanded. On failure returns an empty image and says why
// in *error ("truncated PNG", "not a PNG or JPEG image (first bytes 47 49 46 38)").
cv::Mat DecodeGrey(const void* data, size_t size, std::string* error);

// Reads and decodes an image file; *error starts with the path.
cv::Mat ReadGrey(const std::string& path, std::string* error);

// Encodes an 8-bit image of 1 (grey), 3 (BGR) or 4 (BGRA) channels as PNG at zlib's
// `compression_level` (0-9; 1 is fast and what robots and recorders use). False and *error when
// the image cannot be encoded.
bool EncodePng(const cv::Mat& image, int compression_level, std::vector<uint8_t>* png,
               std::string* error);

// Encodes an 8-bit grey or BGR image as a baseline JPEG at `quality` (1-100), with the settings
// cv::imencode(".jpg", image, {cv::IMWRITE_JPEG_QUALITY, quality}) uses: the same bytes.
bool EncodeJpeg(const cv::Mat& image, int quality, std::vector<uint8_t>* jpeg, std::string* error);

// EncodePng, then the file written whole; *error starts with the path.
bool WritePng(const std::string& path, const cv::Mat& image, int compression_level,
              std::string* error);

}  // namespace visloc::image
