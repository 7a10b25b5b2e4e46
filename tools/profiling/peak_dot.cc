#include "profiling/peak_dot.h"

#include "profiling/cpu_extensions.h"
#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling {
namespace {

// The loop for `type` in this build; nullptr when its file is not compiled.
const internal::PeakKernel* KernelFor(DotType type) {
  switch (type) {
    case DotType::kInt8:
#if SFRT_PEAK_AVX512_VNNI
      return internal::PeakKernelAvx512Vnni();
#else
      return nullptr;
#endif
    case DotType::kInt16:
#if SFRT_PEAK_AVX512_VNNI
      return internal::PeakKernelAvx512VnniInt16();
#else
      return nullptr;
#endif
    case DotType::kBf16:
#if SFRT_PEAK_AVX512_BF16
      return internal::PeakKernelAvx512Bf16();
#else
      return nullptr;
#endif
    case DotType::kAmxInt8:
#if SFRT_PEAK_AMX
      return internal::PeakKernelAmxInt8();
#else
      return nullptr;
#endif
    case DotType::kAmxBf16:
#if SFRT_PEAK_AMX
      return internal::PeakKernelAmxBf16();
#else
      return nullptr;
#endif
  }
  return nullptr;
}

}  // namespace

const char* DotTypeName(DotType type) {
  switch (type) {
    case DotType::kInt8:
      return "int8";
    case DotType::kInt16:
      return "int16";
    case DotType::kBf16:
      return "bf16";
    case DotType::kAmxInt8:
      return "amx_int8";
    case DotType::kAmxBf16:
      return "amx_bf16";
  }
  return "?";
}

bool DotTypeIsInteger(DotType type) {
  return type == DotType::kInt8 || type == DotType::kInt16 || type == DotType::kAmxInt8;
}

std::string PeakDotUnavailable(DotType type) {
  const char* loop = type == DotType::kInt8 || type == DotType::kInt16 ? "AVX-512 VNNI"
                     : type == DotType::kBf16                          ? "AVX512_BF16"
                                                                       : "AMX";
  if (KernelFor(type) == nullptr) {
    return std::string("this build has no ") + loop +
           " loop (x86-64 with AVX-512 kernels only, and a compiler that knows it)";
  }
  switch (type) {
    case DotType::kInt8:
    case DotType::kInt16:
      return internal::Avx512VnniMissing();
    case DotType::kBf16:
      return internal::Avx512Bf16Missing();
    case DotType::kAmxInt8:
    case DotType::kAmxBf16:
      return internal::AmxMissing();
  }
  return "unknown type";
}

Result<PeakDot> MeasurePeakDot(DotType type, int threads, double seconds) {
  const std::string what = std::string("peak ") + DotTypeName(type);
  if (threads < 1) {
    return Status::Error(what + ": threads must be >= 1, got " + std::to_string(threads));
  }
  if (std::string why = PeakDotUnavailable(type); !why.empty()) {
    return Status::Error(what + ": not available (" + why + ")");
  }
  const internal::PeakKernel& kernel = *KernelFor(type);
  PeakDot result;
  result.type = type;
  result.threads = threads;
  result.gops = internal::MeasureGopsPerSecond(kernel, threads, seconds);
  result.gmacs = result.gops / 2;
  result.kernel = kernel.description;
  return result;
}

std::string AmxUnavailable() { return internal::AmxMissing(); }

}  // namespace sfrt::profiling
