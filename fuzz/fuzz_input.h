#pragma once
// Splits a fuzzer's byte string into the parts a target needs: single bytes (choices) and
// length-prefixed chunks (messages, files). Reading past the end yields zeros and empty chunks,
// so every input is a valid split; libFuzzer's mutations then explore each part.
//
// Chunk layout: a 16-bit little-endian length, then that many bytes (cut at the end of input).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

namespace visloc::fuzz {

class FuzzInput {
 public:
  FuzzInput(const uint8_t* data, size_t size) : data_(data), size_(size) {}

  bool empty() const { return position_ >= size_; }

  uint8_t Byte() { return empty() ? 0 : data_[position_++]; }

  std::string Chunk() {
    const size_t length = Byte() | (static_cast<size_t>(Byte()) << 8);
    const size_t take = std::min(length, size_ - std::min(position_, size_));
    std::string chunk(reinterpret_cast<const char*>(data_) + position_, take);
    position_ += take;
    return chunk;
  }

  // Everything not read yet.
  std::string Rest() {
    std::string rest(reinterpret_cast<const char*>(data_) + std::min(position_, size_),
                     size_ - std::min(position_, size_));
    position_ = size_;
    return rest;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t position_ = 0;
};

// The inverse, for writing seeds: appends a chunk with its length prefix.
inline void AppendChunk(const std::string& chunk, std::string* out) {
  const size_t length = std::min<size_t>(chunk.size(), 0xffff);
  out->push_back(static_cast<char>(length & 0xff));
  out->push_back(static_cast<char>(length >> 8));
  out->append(chunk, 0, length);
}

}  // namespace visloc::fuzz
