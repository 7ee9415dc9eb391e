#include "ros/bag/cdr.h"

#include <cstring>

#include "core/util/check.h"

namespace visloc::bag {
namespace {

bool HostIsLittleEndian() {
  const uint16_t one = 1;
  uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

template <typename T>
T Load(const char* bytes, bool swap) {
  char buffer[sizeof(T)];
  std::memcpy(buffer, bytes, sizeof(T));
  if (swap) {
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(buffer[i], buffer[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, buffer, sizeof(T));
  return value;
}

}  // namespace

CdrReader::CdrReader(std::string_view message) {
  if (message.size() < 4) {
    throw InputError(StrCat("CDR: message of ", message.size(), " bytes has no header"));
  }
  const auto kind = static_cast<uint8_t>(message[1]);
  if (message[0] != 0 || kind > 1) {
    throw InputError(StrCat("CDR: encapsulation ", static_cast<int>(static_cast<uint8_t>(message[0])),
                            ".", static_cast<int>(kind),
                            " is not plain CDR (0.0 big-endian or 0.1 little-endian)"));
  }
  swap_ = (kind == 1) != HostIsLittleEndian();
  data_ = message.substr(4);
}

void CdrReader::Align(size_t size, const char* what) {
  const size_t padding = (size - offset_ % size) % size;
  Take(padding, what);
}

const char* CdrReader::Take(size_t size, const char* what) {
  if (size > remaining()) {
    throw InputError(StrCat("CDR: message ends at byte ", data_.size(), " while reading ", what,
                            " (", size, " bytes at offset ", offset_, ")"));
  }
  const char* at = data_.data() + offset_;
  offset_ += size;
  return at;
}

uint8_t CdrReader::U8(const char* what) { return static_cast<uint8_t>(*Take(1, what)); }

uint32_t CdrReader::U32(const char* what) {
  Align(4, what);
  return Load<uint32_t>(Take(4, what), swap_);
}

int32_t CdrReader::I32(const char* what) {
  Align(4, what);
  return Load<int32_t>(Take(4, what), swap_);
}

double CdrReader::F64(const char* what) {
  Align(8, what);
  return Load<double>(Take(8, what), swap_);
}

std::string CdrReader::String(const char* what) {
  const uint32_t length = U32(what);
  if (length == 0) return "";  // Some writers omit the NUL of an empty string.
  const char* bytes = Take(length, what);
  if (bytes[length - 1] != '\0') {
    throw InputError(StrCat("CDR: ", what, " at offset ", offset_ - length,
                            " is not NUL-terminated"));
  }
  return std::string(bytes, length - 1);
}

std::string_view CdrReader::Bytes(const char* what) {
  const uint32_t count = U32(what);
  return std::string_view(Take(count, what), count);
}

std::vector<double> CdrReader::F64Sequence(const char* what) {
  const uint32_t count = U32(what);
  if (count > remaining() / 8) {
    throw InputError(StrCat("CDR: ", what, " claims ", count, " doubles; ", remaining(),
                            " bytes are left"));
  }
  std::vector<double> values(count);
  for (double& v : values) v = F64(what);
  return values;
}

}  // namespace visloc::bag
