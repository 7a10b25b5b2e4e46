// Running the Winograd passes (kernels/winograd_job.h) band by band of tile rows, so that the
// transformed input and products (the scratch) stay small however large the image: a plain
// Winograd convolution, and the fused upsample-conv over its interior. On any parallel-for;
// shared by Session::Run and the tests.
#pragma once

#include <cstddef>

#include "kernels/conv_job.h"
#include "kernels/winograd_job.h"

namespace sfrt {

// The fused upsample-conv's Winograd grid at one size: the interior pixels (those whose 3x3
// window lies inside the cropped upsampled map C, as UpConvRows defines them), the first P row
// and column they need and the 2x2 tiles of P covering them.
struct UpGrid {
  int y_lo = 0, y_hi = 0, x_lo = 0, x_hi = 0;
  int b_lo = 0, c_lo = 0;
  int tiles_h = 0, tiles_w = 0;
};

inline UpGrid UpGridOf(int out_h, int out_w, const Padding& pads, int c_h, int c_w, int crop_top,
                       int crop_left) {
  UpGrid u;
  auto clamp = [](int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); };
  u.y_lo = clamp(pads.top, 0, out_h);
  u.y_hi = clamp(c_h - 2 + pads.top, u.y_lo, out_h);
  u.x_lo = clamp(pads.left, 0, out_w);
  u.x_hi = clamp(c_w - 2 + pads.left, u.x_lo, out_w);
  if (u.y_lo == u.y_hi || u.x_lo == u.x_hi) return u;  // no interior: no tiles
  u.b_lo = (u.y_lo - pads.top + crop_top) >> 1;
  const int b_hi = (u.y_hi - 1 - pads.top + crop_top) >> 1;
  u.c_lo = (u.x_lo - pads.left + crop_left) >> 1;
  const int c_hi = (u.x_hi - 1 - pads.left + crop_left) >> 1;
  u.tiles_h = (b_hi - u.b_lo + 2) / 2;
  u.tiles_w = (c_hi - u.c_lo + 2) / 2;
  return u;
}

// Scratch per band, at least: below this the passes' synchronisation costs more than the
// cache misses saved. Bands are also at least as large as the layer's transformed weights, which
// every band reads once.
constexpr size_t kUpWinogradBandBytes = 16u << 20;

struct WinogradJob {
  WinogradFn fn;
  const WinogradArgs* args;
};

inline void WinogradTrampoline(void* ctx, int begin, int end) {
  const WinogradJob* job = static_cast<const WinogradJob*>(ctx);
  job->fn(*job->args, begin, end);
}

// The interior of a fused upsample-conv on the Winograd phase path, band by band of tile rows;
// `parallel(n, fn, ctx)` runs fn over [0, n) on the session's threads.
template <typename Parallel>
void RunUpWinogradBands(const WinogradKernels& k, const PackedWinograd& w, int band_rows,
                        float* scratch, const ConvArgs& conv, Parallel parallel) {
  const UpGrid u = UpGridOf(conv.out.height, conv.out.width, conv.pads, conv.c_height, conv.c_width,
                            conv.crop_top, conv.crop_left);
  if (u.tiles_h == 0 || u.tiles_w == 0) return;
  WinogradArgs a;
  a.conv = &w;
  a.in = conv.in;
  a.out = conv.out;
  a.tiles_w = u.tiles_w;
  a.up_pad_top = conv.pads.top;
  a.up_pad_left = conv.pads.left;
  a.crop_top = conv.crop_top;
  a.crop_left = conv.crop_left;
  a.y_lo = u.y_lo;
  a.y_hi = u.y_hi;
  a.x_lo = u.x_lo;
  a.x_hi = u.x_hi;
  for (int r0 = 0; r0 < u.tiles_h; r0 += band_rows) {
    a.tiles_h = u.tiles_h - r0 < band_rows ? u.tiles_h - r0 : band_rows;
    a.pads.top = -(u.b_lo + 2 * r0);
    a.pads.left = -u.c_lo;
    const int tiles = a.tiles_h * a.tiles_w;
    a.v = scratch;
    a.m = scratch + static_cast<size_t>(9) * tiles * w.k_stride;
    WinogradJob input_job{k.input, &a};
    WinogradJob product_job{k.product, &a};
    WinogradJob output_job{k.output, &a};
    parallel(tiles, WinogradTrampoline, &input_job);
    parallel(9 * w.blocks, WinogradTrampoline, &product_job);
    parallel(tiles, WinogradTrampoline, &output_job);
  }
}

// Tile rows per band of a grid `tiles_w` tiles wide and `tiles_h` high whose transforms have
// `points` points (alpha^2): the band's scratch stays within kUpWinogradBandBytes, or the
// layer's transformed weights where those are larger.
inline int WinogradBandRowsFor(int points, const PackedWinograd& w, int tiles_h, int tiles_w) {
  const size_t per_tile =
      static_cast<size_t>(points) * (static_cast<size_t>(w.k_stride) + w.n_stride);
  const size_t weights =
      static_cast<size_t>(points) * static_cast<size_t>(w.in_channels) * w.n_stride * sizeof(float);
  const size_t budget = weights > kUpWinogradBandBytes ? weights : kUpWinogradBandBytes;
  const size_t row_floats = per_tile * static_cast<size_t>(tiles_w > 0 ? tiles_w : 1);
  size_t rows = budget / sizeof(float) / row_floats;
  if (rows > static_cast<size_t>(tiles_h)) rows = static_cast<size_t>(tiles_h);
  return rows < 1 ? 1 : static_cast<int>(rows);
}

// Tile rows per band for a fused layer whose interior is `tiles_w` tiles wide and `tiles_h` high.
inline int UpWinogradBandRows(const PackedWinograd& w, int tiles_h, int tiles_w) {
  return WinogradBandRowsFor(9, w, tiles_h, tiles_w);
}

// Scratch floats (v and m) of a band of `band_rows` rows of `tiles_w` tiles whose transforms
// have `points` points.
inline size_t WinogradBandScratchFloatsFor(int points, const PackedWinograd& w, int band_rows,
                                           int tiles_w) {
  return static_cast<size_t>(points) * (static_cast<size_t>(w.k_stride) + w.n_stride) *
         static_cast<size_t>(band_rows) * static_cast<size_t>(tiles_w > 0 ? tiles_w : 1);
}

// Scratch floats of RunUpWinogradBands with `band_rows` rows of `tiles_w` tiles.
inline size_t UpWinogradScratchFloats(const PackedWinograd& w, int band_rows, int tiles_w) {
  return WinogradBandScratchFloatsFor(9, w, band_rows, tiles_w);
}

// Tile rows per band of a plain Winograd convolution with an out_h x out_w output.
inline int WinogradBandRows(const PackedWinograd& w, int out_h, int out_w) {
  return WinogradBandRowsFor(w.alpha * w.alpha, w, WinogradTiles(out_h, w.m),
                             WinogradTiles(out_w, w.m));
}

// Scratch floats of RunWinogradBands with `band_rows` tile rows at an output width of out_w.
inline size_t WinogradBandScratchFloats(const PackedWinograd& w, int band_rows, int out_w) {
  return WinogradBandScratchFloatsFor(w.alpha * w.alpha, w, band_rows, WinogradTiles(out_w, w.m));
}

// A plain Winograd convolution of `in` into `out` (pads: those in effect at this size), band by
// band of `band_rows` tile rows: each band is the same passes over a view of its output rows,
// with the top pad shifted so that its tiles read the input rows they read in the whole grid.
template <typename Parallel>
void RunWinogradBands(const WinogradKernels& k, const PackedWinograd& w, int band_rows,
                      float* scratch, const ConstTensorView& in, const TensorView& out,
                      const Padding& pads, Parallel parallel) {
  const int tiles_h = WinogradTiles(out.height, w.m);
  WinogradArgs a;
  a.conv = &w;
  a.in = in;
  a.tiles_w = WinogradTiles(out.width, w.m);
  a.pads = pads;
  for (int r0 = 0; r0 < tiles_h; r0 += band_rows) {
    const int y0 = r0 * w.m;
    a.tiles_h = tiles_h - r0 < band_rows ? tiles_h - r0 : band_rows;
    a.out = out;
    a.out.data = out.pixel(y0, 0);
    a.out.height = out.height - y0 < a.tiles_h * w.m ? out.height - y0 : a.tiles_h * w.m;
    a.pads.top = pads.top - y0;
    const int tiles = a.tiles_h * a.tiles_w;
    a.v = scratch;
    a.m = scratch + static_cast<size_t>(w.alpha) * w.alpha * tiles * w.k_stride;
    WinogradJob input_job{k.input, &a};
    WinogradJob product_job{k.product, &a};
    WinogradJob output_job{k.output, &a};
    parallel(tiles, WinogradTrampoline, &input_job);
    parallel(w.alpha * w.alpha * w.blocks, WinogradTrampoline, &product_job);
    parallel(tiles, WinogradTrampoline, &output_job);
  }
}

}  // namespace sfrt
