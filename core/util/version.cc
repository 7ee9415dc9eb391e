#include "core/util/version.h"

namespace visloc {

const char* VislocVersion() { return VISLOC_VERSION; }

}  // namespace visloc
