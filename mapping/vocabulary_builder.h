#pragma once
// Training of the hierarchical k-means vocabulary (core/map/vocabulary.h) from a map's
// descriptors, and the keyframes' bag-of-words vectors, for appearance-based relocalization.

#include "core/map/map.h"

namespace visloc::mapping {

struct VocabularyOptions {
  int branching = 8;
  int depth = 3;  // 512 words.
  int kmeans_attempts = 1;
  int kmeans_iterations = 10;
};

// Trains on `descriptors` (float or binary rows). Binary descriptors are clustered in bit space
// and centroids are thresholded back to bits.
Vocabulary TrainVocabulary(const cv::Mat& descriptors, const VocabularyOptions& options);

// IDF word weights from the keyframes' descriptor sets, then their TF-IDF vectors.
void IndexKeyframes(const std::vector<cv::Mat>& keyframe_descriptors, Vocabulary* vocabulary,
                    std::vector<BowVector>* keyframe_vectors);

}  // namespace visloc::mapping
