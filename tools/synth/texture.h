// Textures for the synthetic scene generator: procedural (seeded, tileable) or loaded from
// image files, sampled bilinearly with wrap-around.
#pragma once

#include <string>
#include <vector>

#include "sfrt/status.h"
#include "synth/rng.h"

namespace sfrt::synth {

struct Texture {
  int width = 0;
  int height = 0;
  bool mirror = false;     // wrap by mirroring (image files) instead of repeating (procedural)
  std::vector<float> bgr;  // height * width * 3, values in [0, 1], rows top to bottom

  // Bilinear sample at texel coordinates (u right, v down; texel centres at integers), wrapped.
  void Sample(double u, double v, float out[3]) const;
};

// A tileable 256x256 procedural texture drawn from `rng`: one of fractal value noise with a
// random palette, "dead leaves" (overlapping discs and rectangles), or noisy checks/stripes.
Texture MakeProceduralTexture(Rng& rng, int size = 256);

// Reads an image file (any format OpenCV decodes) as a texture. Errors name the file.
Result<Texture> LoadTextureImage(const std::string& path);

// The image files (png, jpg, jpeg, bmp, ppm, tif, tiff, webp) directly inside `dir`, sorted by
// name so that the choice of texture per object depends only on the seed. Errors when `dir`
// is not a directory or holds no image.
Result<std::vector<std::string>> ListTextureImages(const std::string& dir);

}  // namespace sfrt::synth
