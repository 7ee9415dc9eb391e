#pragma once
// A reader of OMG CDR (Common Data Representation, XCDR version 1), the encoding ROS 2 bags
// store messages in: a 4-byte encapsulation header (0x00 0x00 big-endian or 0x00 0x01
// little-endian, then 2 option bytes), then the fields in order. Each primitive is aligned to
// its own size (up to 8) counted from the end of the header; strings are a uint32 length that
// includes the terminating NUL, then the bytes; sequences are a uint32 count, then the
// elements; fixed-size arrays have no count.
//
// Every read is bounds-checked and throws InputError "CDR: ..." naming what was being read and
// the offset, so a truncated or corrupt message is refused, never read past its end.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace visloc::bag {

class CdrReader {
 public:
  // Reads the encapsulation header; throws InputError for an unknown representation. The
  // reader views `message`, which must outlive it.
  explicit CdrReader(std::string_view message);
  // A temporary string would be gone before the first read.
  explicit CdrReader(std::string&& message) = delete;

  uint8_t U8(const char* what);
  uint32_t U32(const char* what);
  int32_t I32(const char* what);
  double F64(const char* what);
  std::string String(const char* what);
  // A sequence<uint8>: a view into the message (valid while the message is).
  std::string_view Bytes(const char* what);
  std::vector<double> F64Sequence(const char* what);

  size_t offset() const { return offset_; }
  size_t remaining() const { return data_.size() - offset_; }

 private:
  void Align(size_t size, const char* what);
  const char* Take(size_t size, const char* what);

  std::string_view data_;  // The message after the encapsulation header.
  size_t offset_ = 0;
  bool swap_ = false;  // The message's byte order differs from the host's.
};

}  // namespace visloc::bag
