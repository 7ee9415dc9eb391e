#include "core/util/memory.h"

#include <malloc.h>

namespace visloc {

void KeepFreedMemoryForReuse() {
  // Allocations below 64 MiB come from the heap (not fresh mmaps), and up to 256 MiB of free
  // heap is kept instead of being trimmed.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
}

}  // namespace visloc
