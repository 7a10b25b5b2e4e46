// Renders one frame of a synthetic scene: the stereo images and the exact ground truth.
//
// Ground truth, per left pixel (col, row) at frame t (pixel centres at integer coordinates):
// the surface point X0 seen there (nearest hit of the ray through the pixel centre), moved by
// its object's rigid motion to X1 = MovePoint(object, t, X0). Then
//   disparity          d0 = f B / Z0
//   disparity_change   d1 - d0, with d1 = f B / Z1 (same point, same pixel grid as t)
//   optical_flow       (f X1/Z1 + cx - col, f Y1/Z1 + cy - row, 0)
//   scene_flow         X1 - X0 (dX, dY, dZ), camera coordinates, scene units
// Nothing is marked invalid: a point that leaves the view at t+1 keeps the values given by its
// projection (the flow then points outside the image). A point behind the camera at t+1 (Z1 <= 0,
// which the scene generator's motion limits prevent) would give a negative d1.
#pragma once

#include <cstdint>
#include <vector>

#include "synth/scene.h"

namespace sfrt::synth {

struct RenderOptions {
  double noise_sigma = 0;   // photometric noise, in 8-bit grey levels (0..255)
  double blur_sigma = 0;    // Gaussian blur of the images, in pixels (ground truth unaffected)
  uint64_t noise_seed = 0;  // combined with the frame index
  int threads = 1;
};

struct RenderedFrame {
  int height = 0;
  int width = 0;
  std::vector<uint8_t> left;            // H * W * 3, BGR
  std::vector<uint8_t> right;           // H * W * 3, BGR
  std::vector<float> disparity;         // H * W
  std::vector<float> disparity_change;  // H * W
  std::vector<float> optical_flow;      // H * W * 3 (u, v, 0)
  std::vector<float> scene_flow;        // H * W * 3 (dX, dY, dZ)
  std::vector<uint8_t> object;          // H * W: index of the object seen (0 = room)
};

// Renders frame `frame` (0 <= frame < scene.frames).
RenderedFrame RenderFrame(const Scene& scene, int frame, const RenderOptions& options);

}  // namespace sfrt::synth
