#include "synth/render.h"

#include <algorithm>
#include <cmath>
#include <thread>

namespace sfrt::synth {
namespace {

// Runs body(row) for every row, split across `threads` threads in blocks of rows. Each row is
// computed independently, so the result does not depend on the thread count.
template <typename Body>
void ForEachRow(int height, int threads, const Body& body) {
  threads = std::clamp(threads, 1, 64);
  if (threads == 1) {
    for (int r = 0; r < height; ++r) body(r);
    return;
  }
  constexpr int kBlock = 8;
  std::vector<std::thread> pool;
  pool.reserve(static_cast<size_t>(threads));
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (int start = t * kBlock; start < height; start += threads * kBlock) {
        for (int r = start; r < std::min(height, start + kBlock); ++r) body(r);
      }
    });
  }
  for (std::thread& th : pool) th.join();
}

// Separable Gaussian blur with clamped borders. The weights are rounded to multiples of 2^-16
// before normalising, so a last-bit difference in exp() between maths libraries cannot change
// them.
void Blur(std::vector<float>& img, int height, int width, double sigma, int threads) {
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<double> q(static_cast<size_t>(2 * radius + 1));
  double sum = 0;
  for (int k = -radius; k <= radius; ++k) {
    double w = std::floor(std::exp(-0.5 * k * k / (sigma * sigma)) * 65536.0 + 0.5);
    q[static_cast<size_t>(k + radius)] = w;
    sum += w;
  }
  std::vector<float> weights(q.size());
  for (size_t i = 0; i < q.size(); ++i) weights[i] = static_cast<float>(q[i] / sum);

  std::vector<float> tmp(img.size());
  ForEachRow(height, threads, [&](int r) {  // horizontal pass
    for (int c = 0; c < width; ++c) {
      float acc[3] = {0, 0, 0};
      for (int k = -radius; k <= radius; ++k) {
        const int cc = std::clamp(c + k, 0, width - 1);
        const float* p = &img[(static_cast<size_t>(r) * width + cc) * 3];
        const float w = weights[static_cast<size_t>(k + radius)];
        for (int ch = 0; ch < 3; ++ch) acc[ch] += w * p[ch];
      }
      float* o = &tmp[(static_cast<size_t>(r) * width + c) * 3];
      for (int ch = 0; ch < 3; ++ch) o[ch] = acc[ch];
    }
  });
  ForEachRow(height, threads, [&](int r) {  // vertical pass
    for (int c = 0; c < width; ++c) {
      float acc[3] = {0, 0, 0};
      for (int k = -radius; k <= radius; ++k) {
        const int rr = std::clamp(r + k, 0, height - 1);
        const float* p = &tmp[(static_cast<size_t>(rr) * width + c) * 3];
        const float w = weights[static_cast<size_t>(k + radius)];
        for (int ch = 0; ch < 3; ++ch) acc[ch] += w * p[ch];
      }
      float* o = &img[(static_cast<size_t>(r) * width + c) * 3];
      for (int ch = 0; ch < 3; ++ch) o[ch] = acc[ch];
    }
  });
}

std::vector<uint8_t> Finish(std::vector<float>& img, int height, int width,
                            const RenderOptions& options, uint64_t noise_seed) {
  if (options.blur_sigma > 0) Blur(img, height, width, options.blur_sigma, options.threads);
  std::vector<uint8_t> out(img.size());
  Rng rng(noise_seed);
  const double noise = options.noise_sigma;
  for (size_t i = 0; i < img.size(); ++i) {
    double v = static_cast<double>(img[i]) * 255.0;
    if (noise > 0) v += noise * rng.Normalish();
    out[i] = static_cast<uint8_t>(std::clamp(std::floor(v + 0.5), 0.0, 255.0));
  }
  return out;
}

}  // namespace

RenderedFrame RenderFrame(const Scene& scene, int frame, const RenderOptions& options) {
  const Camera& cam = scene.camera;
  const int h = cam.height;
  const int w = cam.width;
  const size_t n = static_cast<size_t>(h) * w;
  RenderedFrame out;
  out.height = h;
  out.width = w;
  std::vector<float> left(n * 3), right(n * 3);
  out.disparity.resize(n);
  out.disparity_change.resize(n);
  out.optical_flow.resize(n * 3);
  out.scene_flow.resize(n * 3);
  out.object.resize(n);
  const double fb = cam.focal * cam.baseline;
  const Vec3 left_origin{0, 0, 0};
  const Vec3 right_origin{cam.baseline, 0, 0};

  ForEachRow(h, options.threads, [&](int r) {
    for (int c = 0; c < w; ++c) {
      const size_t i = static_cast<size_t>(r) * w + c;
      const Vec3 dir{(c - cam.cx) / cam.focal, (r - cam.cy) / cam.focal, 1.0};
      Hit hit;
      if (CastRay(scene, frame, left_origin, dir, &hit)) {
        Shade(scene, frame, hit, &left[i * 3]);
        const SceneObject& obj = scene.objects[static_cast<size_t>(hit.object)];
        const Vec3 x0 = hit.depth * dir;
        const Vec3 x1 = MovePoint(obj, frame, x0);
        const double d0 = fb / x0.z;
        const double d1 = fb / x1.z;
        out.disparity[i] = static_cast<float>(d0);
        out.disparity_change[i] = static_cast<float>(d1 - d0);
        out.optical_flow[i * 3 + 0] = static_cast<float>(cam.focal * x1.x / x1.z + cam.cx - c);
        out.optical_flow[i * 3 + 1] = static_cast<float>(cam.focal * x1.y / x1.z + cam.cy - r);
        out.optical_flow[i * 3 + 2] = 0.0f;
        out.scene_flow[i * 3 + 0] = static_cast<float>(x1.x - x0.x);
        out.scene_flow[i * 3 + 1] = static_cast<float>(x1.y - x0.y);
        out.scene_flow[i * 3 + 2] = static_cast<float>(x1.z - x0.z);
        out.object[i] = static_cast<uint8_t>(hit.object);
      }  // else: unreachable with the camera inside the room; the pixel stays black and zero.
      Hit right_hit;
      if (CastRay(scene, frame, right_origin, dir, &right_hit)) {
        Shade(scene, frame, right_hit, &right[i * 3]);
      }
    }
  });
  out.left = Finish(left, h, w, options, MixSeed(options.noise_seed, frame, 0));
  out.right = Finish(right, h, w, options, MixSeed(options.noise_seed, frame, 1));
  return out;
}

}  // namespace sfrt::synth
