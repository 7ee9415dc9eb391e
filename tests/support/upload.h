#pragma once
// A raw MapAdmin.UploadMap client for end-to-end tests that do what `visloc map upload` never
// does: stop half-way, lie about the checksum, send a file that is not a map.

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <string>

#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::testing {

// Writes the upload header (name, the whole file's size and `crc`) and then the first
// `bytes_to_send` bytes of `bytes` in 64 KiB chunks, as the CLI does. False when the server
// stopped accepting.
inline bool SendUpload(grpc::ClientWriter<v1::UploadChunk>* writer, const std::string& name,
                       const std::string& bytes, uint32_t crc, size_t bytes_to_send) {
  v1::UploadChunk chunk;
  chunk.mutable_header()->set_name(name);
  chunk.mutable_header()->set_size_bytes(bytes.size());
  chunk.mutable_header()->set_crc32(crc);
  if (!writer->Write(chunk)) return false;
  const size_t sent = std::min(bytes_to_send, bytes.size());
  for (size_t at = 0; at < sent; at += 65536) {
    chunk.Clear();
    chunk.set_data(bytes.substr(at, std::min<size_t>(65536, sent - at)));
    if (!writer->Write(chunk)) return false;
  }
  return true;
}

}  // namespace visloc::testing
