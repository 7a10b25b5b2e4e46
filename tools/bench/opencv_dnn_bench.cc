// sfrt_opencv_dnn_bench: times an ONNX file with OpenCV DNN (cv::dnn::readNetFromONNX, OpenCV
// backend, CPU) the way tools/bench/ort_bench.mjs times ONNX Runtime: warm-up, then N runs,
// median / p90 / min, printed as one JSON line. The input is float32 NCHW (1, 12, H, W) with the
// same seeded values as ort_bench.mjs (its LCG, computed in doubles as JavaScript does).
// Usage: sfrt_opencv_dnn_bench MODEL.onnx HEIGHT WIDTH [THREADS=1] [RUNS=5] [WARMUP=1]
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/dnn.hpp>
#include <string>
#include <vector>

namespace {

int ParsePositive(const char* text, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < 1 || v > 1000000) {
    std::fprintf(stderr, "sfrt_opencv_dnn_bench: %s must be a positive integer, got '%s'\n", what,
                 text);
    std::exit(2);
  }
  return static_cast<int>(v);
}

// ort_bench.mjs's input: seed = seed * 1103515245 + 12345 mod 2^32 (exact, in uint32_t) from
// seed 1; value = seed / 2^32 * 255 in double.
void FillLikeOrtBench(float* data, size_t n) {
  uint32_t seed = 1;
  for (size_t i = 0; i < n; ++i) {
    seed = seed * 1103515245u + 12345u;
    data[i] = static_cast<float>(static_cast<double>(seed) / 4294967296.0 * 255.0);
  }
}

double Percentile(const std::vector<double>& sorted, double q) {
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - static_cast<double>(lo));
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4 || argc > 7) {
    std::fprintf(stderr,
                 "usage: sfrt_opencv_dnn_bench MODEL.onnx HEIGHT WIDTH [THREADS=1] [RUNS=5] "
                 "[WARMUP=1]\n");
    return 2;
  }
  const std::string model = argv[1];
  const int height = ParsePositive(argv[2], "HEIGHT");
  const int width = ParsePositive(argv[3], "WIDTH");
  const int threads = argc > 4 ? ParsePositive(argv[4], "THREADS") : 1;
  const int runs = argc > 5 ? ParsePositive(argv[5], "RUNS") : 5;
  const int warmup = argc > 6 ? std::atoi(argv[6]) : 1;

  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  cv::setNumThreads(threads);
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(model);
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "sfrt_opencv_dnn_bench: %s: OpenCV DNN cannot load it: %s\n",
                 model.c_str(), e.what());
    return 1;
  }
  if (net.empty()) {
    std::fprintf(stderr, "sfrt_opencv_dnn_bench: %s: OpenCV DNN loaded an empty network\n",
                 model.c_str());
    return 1;
  }
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);

  const int dims[4] = {1, 12, height, width};
  cv::Mat blob(4, dims, CV_32F);
  FillLikeOrtBench(blob.ptr<float>(), blob.total());

  std::vector<double> ms;
  try {
    for (int i = 0; i < warmup; ++i) {
      net.setInput(blob);
      net.forward();
    }
    for (int i = 0; i < runs; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      net.setInput(blob);
      const cv::Mat out = net.forward();
      const auto t1 = std::chrono::steady_clock::now();
      if (out.empty()) {
        std::fprintf(stderr, "sfrt_opencv_dnn_bench: %s: forward() returned nothing\n",
                     model.c_str());
        return 1;
      }
      ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    }
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "sfrt_opencv_dnn_bench: %s at %dx%d: %s\n", model.c_str(), height, width,
                 e.what());
    return 1;
  }
  std::sort(ms.begin(), ms.end());
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf(
      "{\"peer\":\"opencv-dnn\",\"version\":%s,\"model\":%s,\"height\":%d,\"width\":%d,"
      "\"threads\":%d,\"runs\":%d,\"median_ms\":%.3f,\"p90_ms\":%.3f,\"min_ms\":%.3f,"
      "\"peak_rss_mib\":%.1f}\n",
      JsonString(CV_VERSION).c_str(), JsonString(model).c_str(), height, width, threads, runs,
      Percentile(ms, 0.5), Percentile(ms, 0.9), ms.front(),
      static_cast<double>(usage.ru_maxrss) / 1024.0);
  return 0;
}
