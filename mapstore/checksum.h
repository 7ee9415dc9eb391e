#pragma once
// CRC-32 (zlib's polynomial), the checksum of map content and of map files in transit.

#include <cstdint>
#include <string_view>

namespace visloc::mapstore {

// The CRC-32 of `bytes`, continuing from `previous` (the CRC of what came before, 0 to start),
// so a stream can be checked chunk by chunk.
uint32_t Crc32(std::string_view bytes, uint32_t previous = 0);

}  // namespace visloc::mapstore
