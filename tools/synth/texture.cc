#include "synth/texture.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "sfrt/camera/image_file.h"

namespace sfrt::synth {
namespace {

// Index into [0, n) by repeating or mirroring.
int WrapIndex(long long i, int n, bool mirror) {
  if (!mirror) {
    long long m = i % n;
    return static_cast<int>(m < 0 ? m + n : m);
  }
  const long long period = 2LL * n;
  long long m = i % period;
  if (m < 0) m += period;
  return static_cast<int>(m < n ? m : period - 1 - m);
}

double Smooth(double t) { return t * t * (3.0 - 2.0 * t); }

// Periodic value noise: a random lattice of `cells` x `cells` values in [0, 1].
class ValueNoise {
 public:
  ValueNoise(Rng& rng, int cells) : cells_(cells), values_(static_cast<size_t>(cells) * cells) {
    for (double& v : values_) v = rng.Uniform();
  }
  // x, y in [0, 1): one period of the texture.
  double At(double x, double y) const {
    const double fx = x * cells_;
    const double fy = y * cells_;
    const long long ix = static_cast<long long>(std::floor(fx));
    const long long iy = static_cast<long long>(std::floor(fy));
    const double tx = Smooth(fx - static_cast<double>(ix));
    const double ty = Smooth(fy - static_cast<double>(iy));
    auto v = [&](long long i, long long j) {
      return values_[static_cast<size_t>(WrapIndex(j, cells_, false)) * cells_ +
                     WrapIndex(i, cells_, false)];
    };
    const double top = v(ix, iy) + (v(ix + 1, iy) - v(ix, iy)) * tx;
    const double bottom = v(ix, iy + 1) + (v(ix + 1, iy + 1) - v(ix, iy + 1)) * tx;
    return top + (bottom - top) * ty;
  }

 private:
  int cells_;
  std::vector<double> values_;
};

// Fractal sum of value-noise octaves, normalised to about [0, 1].
class Fbm {
 public:
  Fbm(Rng& rng, int base_cells, int octaves) {
    int cells = base_cells;
    for (int o = 0; o < octaves; ++o, cells *= 2) octaves_.emplace_back(rng, cells);
  }
  double At(double x, double y) const {
    double sum = 0, amp = 1, total = 0;
    for (const ValueNoise& n : octaves_) {
      sum += amp * n.At(x, y);
      total += amp;
      amp *= 0.55;
    }
    return sum / total;
  }

 private:
  std::vector<ValueNoise> octaves_;
};

struct Color {
  double c[3];
};

Color RandomColor(Rng& rng) { return {{rng.Uniform(), rng.Uniform(), rng.Uniform()}}; }

Color Lerp(const Color& a, const Color& b, double t) {
  return {{a.c[0] + (b.c[0] - a.c[0]) * t, a.c[1] + (b.c[1] - a.c[1]) * t,
           a.c[2] + (b.c[2] - a.c[2]) * t}};
}

void Put(Texture& tex, int x, int y, const Color& c) {
  float* p = &tex.bgr[(static_cast<size_t>(y) * tex.width + x) * 3];
  for (int k = 0; k < 3; ++k) p[k] = static_cast<float>(std::clamp(c.c[k], 0.0, 1.0));
}

// Palette of three colours, t in [0, 1] maps through them piecewise linearly.
Color Palette(const Color p[3], double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t < 0.5 ? Lerp(p[0], p[1], t * 2) : Lerp(p[1], p[2], t * 2 - 1);
}

void NoiseTexture(Rng& rng, Texture& tex) {
  Color palette[3] = {RandomColor(rng), RandomColor(rng), RandomColor(rng)};
  Fbm fbm(rng, 2 << rng.Below(3), 5);
  const double contrast = rng.Uniform(1.5, 3.0);
  for (int y = 0; y < tex.height; ++y) {
    for (int x = 0; x < tex.width; ++x) {
      double n = fbm.At(static_cast<double>(x) / tex.width, static_cast<double>(y) / tex.height);
      Put(tex, x, y, Palette(palette, 0.5 + (n - 0.5) * contrast));
    }
  }
}

void DeadLeavesTexture(Rng& rng, Texture& tex) {
  const int n = tex.width;
  std::vector<Color> img(static_cast<size_t>(n) * n, RandomColor(rng));
  const int shapes = 250 + rng.Below(250);
  for (int s = 0; s < shapes; ++s) {
    const Color c = RandomColor(rng);
    const double cx = rng.Uniform(0, n);
    const double cy = rng.Uniform(0, n);
    // Sizes from a power law: many small shapes, a few large ones.
    const double u = rng.Uniform(0.05, 1.0);
    const double r = std::clamp(2.0 / (u * u), 2.0, n * 0.25);
    const bool disc = rng.Below(2) == 0;
    const double rx = r;
    const double ry = disc ? r : r * rng.Uniform(0.3, 1.0);
    const int x0 = static_cast<int>(std::floor(cx - rx));
    const int x1 = static_cast<int>(std::ceil(cx + rx));
    const int y0 = static_cast<int>(std::floor(cy - ry));
    const int y1 = static_cast<int>(std::ceil(cy + ry));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double dx = (x - cx) / rx;
        const double dy = (y - cy) / ry;
        if (disc ? dx * dx + dy * dy > 1.0 : (std::fabs(dx) > 1.0 || std::fabs(dy) > 1.0)) {
          continue;
        }
        img[static_cast<size_t>(WrapIndex(y, n, false)) * n + WrapIndex(x, n, false)] = c;
      }
    }
  }
  Fbm fbm(rng, 8, 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double shade =
          0.75 + 0.5 * fbm.At(static_cast<double>(x) / n, static_cast<double>(y) / n);
      Color c = img[static_cast<size_t>(y) * n + x];
      for (double& v : c.c) v *= shade;
      Put(tex, x, y, c);
    }
  }
}

void ChecksTexture(Rng& rng, Texture& tex) {
  const Color a = RandomColor(rng);
  const Color b = RandomColor(rng);
  const int cells = 2 << rng.Below(4);  // 2, 4, 8 or 16 per period: tileable
  const bool stripes = rng.Below(2) == 0;
  Fbm warp(rng, 4, 3);
  Fbm shade(rng, 8, 4);
  const double warp_amount = rng.Uniform(0.0, 0.6) / cells;
  for (int y = 0; y < tex.height; ++y) {
    for (int x = 0; x < tex.width; ++x) {
      const double fx = static_cast<double>(x) / tex.width;
      const double fy = static_cast<double>(y) / tex.height;
      const double w = (warp.At(fx, fy) - 0.5) * warp_amount;
      const long long i = static_cast<long long>(std::floor((fx + w) * cells));
      const long long j = static_cast<long long>(std::floor((fy - w) * cells));
      const bool odd = stripes ? (i & 1) != 0 : ((i + j) & 1) != 0;
      Color c = odd ? a : b;
      const double s = 0.6 + 0.8 * shade.At(fx, fy);
      for (double& v : c.c) v *= s;
      Put(tex, x, y, c);
    }
  }
}

bool IsImageExtension(std::string ext) {
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* known :
       {".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".pgm", ".tif", ".tiff", ".webp"}) {
    if (ext == known) return true;
  }
  return false;
}

}  // namespace

void Texture::Sample(double u, double v, float out[3]) const {
  const double fu = std::floor(u);
  const double fv = std::floor(v);
  const double tu = u - fu;
  const double tv = v - fv;
  // Texture coordinates can be large far away on a tilted plane; fold them into a few periods
  // first so the conversion to an integer cannot overflow.
  const double pu = 2.0 * width;
  const double pv = 2.0 * height;
  const long long iu = static_cast<long long>(fu - std::floor(fu / pu) * pu);
  const long long iv = static_cast<long long>(fv - std::floor(fv / pv) * pv);
  const int x0 = WrapIndex(iu, width, mirror);
  const int x1 = WrapIndex(iu + 1, width, mirror);
  const int y0 = WrapIndex(iv, height, mirror);
  const int y1 = WrapIndex(iv + 1, height, mirror);
  const float* p00 = &bgr[(static_cast<size_t>(y0) * width + x0) * 3];
  const float* p01 = &bgr[(static_cast<size_t>(y0) * width + x1) * 3];
  const float* p10 = &bgr[(static_cast<size_t>(y1) * width + x0) * 3];
  const float* p11 = &bgr[(static_cast<size_t>(y1) * width + x1) * 3];
  const float a = static_cast<float>(tu);
  const float b = static_cast<float>(tv);
  for (int k = 0; k < 3; ++k) {
    const float top = p00[k] + (p01[k] - p00[k]) * a;
    const float bottom = p10[k] + (p11[k] - p10[k]) * a;
    out[k] = top + (bottom - top) * b;
  }
}

Texture MakeProceduralTexture(Rng& rng, int size) {
  Texture tex;
  tex.width = size;
  tex.height = size;
  tex.bgr.assign(static_cast<size_t>(size) * size * 3, 0.0f);
  switch (rng.Below(3)) {
    case 0:
      NoiseTexture(rng, tex);
      break;
    case 1:
      DeadLeavesTexture(rng, tex);
      break;
    default:
      ChecksTexture(rng, tex);
      break;
  }
  return tex;
}

Result<Texture> LoadTextureImage(const std::string& path) {
  cv::Mat img;
  if (std::string why = camera::ReadImageFile(path, cv::IMREAD_COLOR, &img); !why.empty()) {
    return Status::Error("texture '" + path + "': " + why);
  }
  if (img.depth() != CV_8U || img.channels() != 3 || img.rows < 2 || img.cols < 2) {
    return Status::Error("texture '" + path + "': expected an 8-bit colour image of 2x2 or more");
  }
  Texture tex;
  tex.width = img.cols;
  tex.height = img.rows;
  tex.mirror = true;
  tex.bgr.resize(static_cast<size_t>(img.rows) * img.cols * 3);
  for (int y = 0; y < img.rows; ++y) {
    const uint8_t* row = img.ptr<uint8_t>(y);
    float* dst = &tex.bgr[static_cast<size_t>(y) * img.cols * 3];
    for (int i = 0; i < img.cols * 3; ++i) dst[i] = static_cast<float>(row[i]) / 255.0f;
  }
  return tex;
}

Result<std::vector<std::string>> ListTextureImages(const std::string& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    return Status::Error("texture folder '" + dir + "' is not a directory");
  }
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && IsImageExtension(entry.path().extension().string())) {
      files.push_back(entry.path().string());
    }
  }
  if (ec) return Status::Error("texture folder '" + dir + "': " + ec.message());
  if (files.empty()) {
    return Status::Error("texture folder '" + dir +
                         "' holds no image file (.png, .jpg, .jpeg, .bmp, .ppm, .pgm, .tif, "
                         ".tiff, .webp)");
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace sfrt::synth
