// The entries of an ISA's kernel tables (conv_job.h, winograd_job.h), built from the shared
// drivers for that ISA's vector vocabulary `V`. Each kernels/<isa>/conv2d_<isa>.cc keeps only what
// differs: V, its register tiles and the kernels' names. The drivers' instantiations are the
// table's function pointers themselves (their signatures are ConvRowsFn and WinogradFn), with
// internal linkage as every template on an ISA's V (conv_driver_inl.h).
//
// The kernels' names (what profiles and `sfrt bench` show) stay spelled out in the ISA files,
// beside the template arguments of the tile they name, so a name in a profile greps to its file.
#pragma once

#include "kernels/conv_job.h"
#include "kernels/simd/conv_driver_inl.h"
#include "kernels/simd/conv_few_out_inl.h"
#include "kernels/simd/winograd_driver_inl.h"
#include "kernels/winograd_job.h"

namespace sfrt::simd {

// The direct and fused upsample-conv kernels on the MR pixels x NV vectors register tile.
template <typename V, int MR, int NV>
constexpr ConvKernelVariant ConvVariant(const char* conv_name, const char* upconv_name) {
  return {NV * V::kLanes, ConvRows<V, MR, NV>, UpConvRows<V, MR, NV>, conv_name, upconv_name};
}

// Winograd F(M x M, 3 x 3), M = 2 or 4, with the products on the MR x NV tile.
template <typename V, int M, int MR, int NV>
constexpr WinogradKernels WinogradConvKernels(const char* name) {
  return {M,
          NV * V::kLanes,
          WinogradInput<V, WinogradTransform<M>>,
          WinogradProduct<V, MR, NV>,
          WinogradOutput<V, WinogradTransform<M>>,
          name};
}

// The fused upsample-conv's F(2x2, 2x2) phase kernels, with the products on the MR x NV tile.
template <typename V, int MR, int NV>
constexpr WinogradKernels WinogradUpConvKernels(const char* name) {
  return {2,
          NV * V::kLanes,
          WinogradInput<V, WinogradPhaseTransform>,
          WinogradProduct<V, MR, NV>,
          WinogradUpOutput<V>,
          name};
}

}  // namespace sfrt::simd
