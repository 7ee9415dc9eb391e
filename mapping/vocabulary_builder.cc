#include "mapping/vocabulary_builder.h"

#include <cmath>
#include <algorithm>
#include <vector>

#include <opencv2/core.hpp>

#include "core/map/vocabulary.h"
#include "core/util/check.h"

namespace visloc::mapping {
namespace {

// Descriptors as float rows for k-means: binary bytes expand to one float per bit.
cv::Mat ToFloatRows(const cv::Mat& descriptors) {
  if (descriptors.type() == CV_32F) return descriptors;
  cv::Mat bits(descriptors.rows, descriptors.cols * 8, CV_32F);
  for (int r = 0; r < descriptors.rows; ++r) {
    for (int c = 0; c < descriptors.cols * 8; ++c) {
      bits.at<float>(r, c) = (descriptors.at<uint8_t>(r, c / 8) >> (c % 8)) & 1 ? 1.0f : 0.0f;
    }
  }
  return bits;
}

cv::Mat FromFloatRow(const cv::Mat& center, int type, int cols) {
  if (type == CV_32F) return center.clone();
  cv::Mat bytes(1, cols, CV_8U, cv::Scalar(0));
  for (int c = 0; c < cols * 8; ++c) {
    if (center.at<float>(0, c) >= 0.5f)
      bytes.at<uint8_t>(0, c / 8) |= static_cast<uint8_t>(1 << (c % 8));
  }
  return bytes;
}

// Fills the children rows of one node (level `level`, index `index` within it) and recurses.
void Split(const cv::Mat& samples, const VocabularyOptions& options, int level, int index, int type,
           int cols, std::vector<int>* level_starts, cv::Mat* centroids) {
  if (level >= options.depth) return;
  const int b = options.branching;
  cv::Mat labels, centers;
  if (samples.rows >= b) {
    cv::kmeans(samples, b, labels,
               cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                                options.kmeans_iterations, 1e-4),
               options.kmeans_attempts, cv::KMEANS_PP_CENTERS, centers);
  } else {
    // Too few samples to split: children repeat the samples (or the last one).
    centers = cv::Mat(b, samples.cols, CV_32F, cv::Scalar(0));
    labels = cv::Mat(samples.rows, 1, CV_32S);
    for (int c = 0; c < b; ++c) {
      if (samples.rows > 0) samples.row(std::min(c, samples.rows - 1)).copyTo(centers.row(c));
    }
    for (int r = 0; r < samples.rows; ++r) labels.at<int>(r) = r;
  }
  for (int c = 0; c < b; ++c) {
    const int row = (*level_starts)[level] + index * b + c;
    FromFloatRow(centers.row(c), type, cols).copyTo(centroids->row(row));
    cv::Mat child;
    for (int r = 0; r < samples.rows; ++r) {
      if (labels.at<int>(r) == c) child.push_back(samples.row(r));
    }
    if (child.empty()) child = centers.row(c).clone();
    Split(child, options, level + 1, index * b + c, type, cols, level_starts, centroids);
  }
}

}  // namespace

Vocabulary TrainVocabulary(const cv::Mat& descriptors, const VocabularyOptions& options) {
  VISLOC_CHECK(options.branching >= 2 && options.depth >= 1, "vocabulary shape");
  VISLOC_CHECK(!descriptors.empty(), "no descriptors to train a vocabulary on");
  Vocabulary vocabulary;
  vocabulary.branching = options.branching;
  vocabulary.depth = options.depth;
  std::vector<int> level_starts;
  int nodes = 0, level_size = 1;
  for (int level = 0; level < options.depth; ++level) {
    level_starts.push_back(nodes);
    level_size *= options.branching;
    nodes += level_size;
  }
  vocabulary.centroids = cv::Mat(nodes, descriptors.cols, descriptors.type(), cv::Scalar(0));
  cv::setRNGSeed(12345);  // k-means++ seeding draws from OpenCV's generator: keep builds repeatable
  Split(ToFloatRows(descriptors), options, 0, 0, descriptors.type(), descriptors.cols,
        &level_starts, &vocabulary.centroids);
  vocabulary.word_weights.assign(level_size, 1.0f);
  return vocabulary;
}

void IndexKeyframes(const std::vector<cv::Mat>& keyframe_descriptors, Vocabulary* vocabulary,
                    std::vector<BowVector>* keyframe_vectors) {
  const size_t words = vocabulary->word_count();
  std::vector<int> documents(words, 0);
  std::vector<std::vector<uint32_t>> keyframe_words;
  for (const cv::Mat& descriptors : keyframe_descriptors) {
    keyframe_words.push_back(LookupWords(*vocabulary, descriptors));
    std::vector<uint32_t> seen = keyframe_words.back();
    std::sort(seen.begin(), seen.end());
    seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
    for (uint32_t w : seen) ++documents[w];
  }
  const double n = static_cast<double>(std::max<size_t>(1, keyframe_descriptors.size()));
  for (size_t w = 0; w < words; ++w) {
    // Words no keyframe has get the largest weight: rare evidence is strong evidence.
    vocabulary->word_weights[w] =
        static_cast<float>(std::log(n / std::max(1, documents[w])) + 1e-3);
  }
  keyframe_vectors->clear();
  for (const std::vector<uint32_t>& words_of_keyframe : keyframe_words) {
    keyframe_vectors->push_back(BowFromWords(*vocabulary, words_of_keyframe));
  }
}

}  // namespace visloc::mapping
