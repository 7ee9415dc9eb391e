// The codec against OpenCV's imgcodecs, which the product used before and which wraps the same
// libraries: the same pixels from every image the product reads, the same bytes from the
// encoders, and a named error for every kind of broken input.

#include "core/image/image_codec.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <png.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/util/temp_dir.h"

namespace visloc::image {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::vector<uint8_t> FileBytes(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

// Pixels equal, or the first difference.
::testing::AssertionResult SamePixels(const cv::Mat& ours, const cv::Mat& opencv) {
  if (ours.size() != opencv.size() || ours.type() != opencv.type()) {
    return ::testing::AssertionFailure()
           << "ours " << ours.cols << "x" << ours.rows << " type " << ours.type() << ", OpenCV's "
           << opencv.cols << "x" << opencv.rows << " type " << opencv.type();
  }
  cv::Mat differ;
  cv::compare(ours.reshape(1), opencv.reshape(1), differ, cv::CMP_NE);
  const int count = cv::countNonZero(differ);
  if (count == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << count << " pixels differ";
}

::testing::AssertionResult DecodesAsOpenCv(const std::vector<uint8_t>& bytes) {
  std::string error;
  const cv::Mat ours = DecodeGrey(bytes.data(), bytes.size(), &error);
  if (ours.empty()) return ::testing::AssertionFailure() << "not decoded: " << error;
  return SamePixels(ours, cv::imdecode(bytes, cv::IMREAD_GRAYSCALE));
}

// A smooth colour image with texture, as a camera's.
cv::Mat ColourScene(int width, int height) {
  cv::Mat noise(height, width, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat scene;
  cv::GaussianBlur(noise, scene, cv::Size(5, 5), 1.5);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) scene.at<cv::Vec3b>(y, x)[0] = static_cast<uint8_t>(x + y);
  }
  return scene;
}

// A PNG of a kind OpenCV's encoder does not write (palette, 1- or 2-bit grey, grey with alpha,
// interlaced), through libpng. `samples`: one row of bytes per image row, as libpng packs them.
std::vector<uint8_t> LibpngFile(int width, int height, int bit_depth, int color_type,
                                bool interlaced, const std::vector<std::vector<uint8_t>>& samples,
                                const std::vector<png_color>& palette = {}) {
  std::vector<uint8_t> out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_set_write_fn(
      png, &out,
      [](png_structp p, png_bytep data, png_size_t n) {
        auto* bytes = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(p));
        bytes->insert(bytes->end(), data, data + n);
      },
      nullptr);
  png_set_IHDR(png, info, width, height, bit_depth, color_type,
               interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  if (!palette.empty()) png_set_PLTE(png, info, palette.data(), static_cast<int>(palette.size()));
  png_write_info(png, info);
  std::vector<png_bytep> rows;
  for (const auto& row : samples) rows.push_back(const_cast<uint8_t*>(row.data()));
  png_write_image(png, rows.data());
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return out;
}

std::vector<uint8_t> Encoded(const std::string& ext, const cv::Mat& image,
                             const std::vector<int>& params = {}) {
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes, params));
  return bytes;
}

TEST(ImageCodecTest, EveryImageOfTheRealRecordingsDecodesAsOpenCvDecodesIt) {
  const fs::path real = VISLOC_REAL_DATA;
  if (!fs::is_directory(real)) GTEST_SKIP() << "no real recordings at " << real;
  int images = 0;
  for (const auto& entry : fs::recursive_directory_iterator(real)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".png" && ext != ".jpg") continue;
    const std::vector<uint8_t> bytes = FileBytes(entry.path().string());
    ASSERT_TRUE(DecodesAsOpenCv(bytes)) << entry.path();
    ++images;
  }
  EXPECT_GT(images, 500);
}

TEST(ImageCodecTest, PngsOfEveryColourTypeAndDepthDecodeAsOpenCvDecodesThem) {
  const cv::Mat bgr = ColourScene(97, 61);  // Odd sizes: no row is a multiple of anything.
  cv::Mat grey, bgra, grey16, bgr16;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  bgra.forEach<cv::Vec4b>([](cv::Vec4b& p, const int* at) { p[3] = uint8_t(at[1] * 4); });
  grey.convertTo(grey16, CV_16U, 257.0, 3.0);
  bgr.convertTo(bgr16, CV_16U, 257.0, 100.0);
  for (const cv::Mat& image : {grey, bgr, bgra, grey16, bgr16}) {
    for (int level : {0, 1, 9}) {
      EXPECT_TRUE(DecodesAsOpenCv(Encoded(".png", image, {cv::IMWRITE_PNG_COMPRESSION, level})))
          << "channels " << image.channels() << ", depth " << image.depth();
    }
  }
  // What OpenCV does not write: palette, 1- and 2-bit grey, grey with alpha, interlaced.
  const int width = 37, height = 23;
  std::vector<png_color> palette;
  for (int i = 0; i < 16; ++i) {
    palette.push_back({uint8_t(i * 16), uint8_t(255 - i * 9), uint8_t((i * 53) % 256)});
  }
  std::vector<std::vector<uint8_t>> indices(height), bits(height), pairs(height),
      grey_alpha(height), rgb(height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      indices[y].push_back(uint8_t((x * 3 + y) % 16));
      grey_alpha[y].push_back(uint8_t(x * 7 + y));
      grey_alpha[y].push_back(uint8_t(255 - x));
      for (int c = 0; c < 3; ++c) rgb[y].push_back(uint8_t(x * (c + 2) + y * 5));
    }
    for (int b = 0; b < (width + 7) / 8; ++b) bits[y].push_back(uint8_t(0xa5 ^ (y * 17 + b)));
    for (int b = 0; b < (width + 3) / 4; ++b) pairs[y].push_back(uint8_t(0x1b + y * 31 + b));
  }
  for (bool interlaced : {false, true}) {
    SCOPED_TRACE(interlaced ? "interlaced" : "not interlaced");
    EXPECT_TRUE(DecodesAsOpenCv(
        LibpngFile(width, height, 8, PNG_COLOR_TYPE_PALETTE, interlaced, indices, palette)));
    EXPECT_TRUE(
        DecodesAsOpenCv(LibpngFile(width, height, 1, PNG_COLOR_TYPE_GRAY, interlaced, bits)));
    EXPECT_TRUE(
        DecodesAsOpenCv(LibpngFile(width, height, 2, PNG_COLOR_TYPE_GRAY, interlaced, pairs)));
    EXPECT_TRUE(DecodesAsOpenCv(
        LibpngFile(width, height, 8, PNG_COLOR_TYPE_GRAY_ALPHA, interlaced, grey_alpha)));
    EXPECT_TRUE(DecodesAsOpenCv(LibpngFile(width, height, 8, PNG_COLOR_TYPE_RGB, interlaced, rgb)));
  }
}

TEST(ImageCodecTest, JpegsDecodeAsOpenCvDecodesThemAndEncodeToItsBytes) {
  const cv::Mat bgr = ColourScene(161, 83);
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  for (const cv::Mat& image : {grey, bgr}) {
    for (int quality : {30, 80, 95, 100}) {
      SCOPED_TRACE("channels " + std::to_string(image.channels()) + ", quality " +
                   std::to_string(quality));
      const std::vector<uint8_t> opencv =
          Encoded(".jpg", image, {cv::IMWRITE_JPEG_QUALITY, quality});
      EXPECT_TRUE(DecodesAsOpenCv(opencv));
      std::vector<uint8_t> ours;
      std::string error;
      ASSERT_TRUE(EncodeJpeg(image, quality, &ours, &error)) << error;
      EXPECT_EQ(ours, opencv);
    }
  }
}

TEST(ImageCodecTest, PngsEncodeToOpenCvsBytesAndBackToTheSamePixels) {
  const cv::Mat bgr = ColourScene(80, 45);
  cv::Mat grey, bgra;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  for (const cv::Mat& image : {grey, bgr, bgra}) {
    for (int level : {0, 1, 6}) {
      SCOPED_TRACE("channels " + std::to_string(image.channels()) + ", level " +
                   std::to_string(level));
      std::vector<uint8_t> ours;
      std::string error;
      ASSERT_TRUE(EncodePng(image, level, &ours, &error)) << error;
      EXPECT_EQ(ours, Encoded(".png", image, {cv::IMWRITE_PNG_COMPRESSION, level}));
      EXPECT_TRUE(SamePixels(cv::imdecode(ours, cv::IMREAD_UNCHANGED), image));
    }
  }
}

TEST(ImageCodecTest, AWrittenPngIsReadBack) {
  TempDir dir("image_codec_test");
  const std::string path = dir.path() + "/grey.png";
  cv::Mat grey;
  cv::cvtColor(ColourScene(64, 48), grey, cv::COLOR_BGR2GRAY);
  std::string error;
  ASSERT_TRUE(WritePng(path, grey, 1, &error)) << error;
  EXPECT_TRUE(SamePixels(ReadGrey(path, &error), grey)) << error;
  EXPECT_FALSE(WritePng(dir.path() + "/no/such/dir/x.png", grey, 1, &error));
  EXPECT_THAT(error, HasSubstr("no/such/dir/x.png: cannot write"));
}

TEST(ImageCodecTest, BrokenInputIsRefusedWithItsReason) {
  cv::Mat grey;
  cv::cvtColor(ColourScene(64, 48), grey, cv::COLOR_BGR2GRAY);
  const std::vector<uint8_t> png = Encoded(".png", grey);
  const std::vector<uint8_t> jpeg = Encoded(".jpg", grey);
  auto refused = [](const std::vector<uint8_t>& bytes) {
    std::string error;
    const cv::Mat decoded = DecodeGrey(bytes.data(), bytes.size(), &error);
    EXPECT_TRUE(decoded.empty());
    return error;
  };
  EXPECT_EQ(refused({}), "no image data (0 bytes)");
  EXPECT_EQ(refused({'G', 'I', 'F', '8', '9', 'a'}),
            "not a PNG or JPEG image (first bytes 47 49 46 38)");
  EXPECT_EQ(refused({png.begin(), png.begin() + png.size() / 2}),
            "truncated PNG: the data ends early");
  EXPECT_EQ(refused({jpeg.begin(), jpeg.begin() + jpeg.size() / 2}),
            "truncated JPEG: the data ends before the image does");
  std::vector<uint8_t> bad_crc = png;
  bad_crc[40] ^= 0xff;  // Inside the first IDAT chunk.
  EXPECT_THAT(refused(bad_crc), HasSubstr("PNG"));
  std::vector<uint8_t> bad_jpeg = jpeg;
  for (size_t i = 2; i < 40; ++i) bad_jpeg[i] = 0x00;  // The headers gone.
  EXPECT_THAT(refused(bad_jpeg), HasSubstr("JPEG"));

  // A header that claims 100000 x 100000 pixels, with a valid CRC: refused before allocation.
  std::vector<uint8_t> huge = png;
  for (int i = 0; i < 2; ++i) {
    huge[16 + 4 * i] = 0x00, huge[17 + 4 * i] = 0x01, huge[18 + 4 * i] = 0x86;
    huge[19 + 4 * i] = 0xa0;
  }
  const uLong crc = crc32(0, huge.data() + 12, 17);  // "IHDR" and its 13 bytes.
  for (int i = 0; i < 4; ++i) huge[29 + i] = uint8_t(crc >> (24 - 8 * i));
  EXPECT_EQ(refused(huge), "PNG of 100000x100000 pixels, more than the 134217728 decoded at most");

  std::string error;
  EXPECT_TRUE(ReadGrey("/nonexistent/frame.png", &error).empty());
  EXPECT_EQ(error, "/nonexistent/frame.png: cannot open");
  std::vector<uint8_t> out;
  EXPECT_FALSE(EncodeJpeg(cv::Mat(4, 4, CV_16UC1), 90, &out, &error));
  EXPECT_EQ(error, "cannot encode not an 8-bit image as JPEG");
  EXPECT_FALSE(EncodePng(cv::Mat(), 1, &out, &error));
  EXPECT_EQ(error, "cannot encode an empty image as PNG");
}

TEST(ImageCodecTest, FormatsAreToldByTheirFirstBytes) {
  const uint8_t png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const uint8_t jpeg[3] = {0xff, 0xd8, 0xff};
  EXPECT_EQ(SniffFormat(png, 8), Format::kPng);
  EXPECT_EQ(SniffFormat(png, 7), Format::kUnknown);
  EXPECT_EQ(SniffFormat(jpeg, 3), Format::kJpeg);
  EXPECT_EQ(SniffFormat(jpeg, 2), Format::kUnknown);
}

}  // namespace
}  // namespace visloc::image
