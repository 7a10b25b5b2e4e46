#include "kernels/int8_job.h"

namespace sfrt {

const IsaInt8Kernels* Int8KernelsFor(Isa /*isa*/) { return nullptr; }

}  // namespace sfrt
