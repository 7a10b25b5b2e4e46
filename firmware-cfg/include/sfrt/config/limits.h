// The one table of limits on what a user gives sfrt: `sfrt` command-line options and deployment
// profiles (firmware-cfg/*.yaml) both check against it, with the same words, so a value means
// the same thing (or is refused the same way) wherever it is written. firmware-cfg/README.md
// ("Limits") shows the table; a test compares the two.
//
// Sizes are always written height x width ("HxW"), as --size takes them.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace sfrt::config {

// An integer range lo..hi, named for messages.
struct IntRange {
  const char* what;  // "input size", "threads", ...
  long long lo;
  long long hi;
  const char* unit;  // "pixels per side", ...; may be ""
  const char* note;  // what a special value means ("0: one per CPU"); may be ""
};

// Network input size (model input after resizing/rectifying), each side: --size of run, infer,
// bench, eval and inspect, the shape of an `infer --input-npy` array, and the profile's
// model.input_height/input_width and latency.fallback_height/fallback_width.
inline constexpr IntRange kInputSide = {"input size", 16, 4096, "pixels per side", ""};
// A plain-tensor input (a model whose input is not images, e.g. an operator test), each side: the
// shape of an `infer --input-npy` array for such a model. The model's own shapes decide whether
// its layers fit a small size.
inline constexpr IntRange kTensorSide = {"tensor size", 1, 4096, "pixels per side",
                                         "models whose input is a plain tensor"};
// Camera and image frame size, each side: run --camera-size, synth --size, the profile's
// camera.width/height (a side-by-side frame: each half).
inline constexpr IntRange kFrameSide = {"frame size", 16, 8192, "pixels per side", ""};
// Threads of inference (and of synth's renderer): --threads of run, bench, synth, and the
// profile's stages.<stage>.threads. 0 is one per CPU everywhere.
inline constexpr IntRange kThreads = {"threads", 0, 256, "", "0: one per CPU"};
// V4L2 buffers per camera: run --buffers, camera.buffer_count.
inline constexpr IntRange kCameraBuffers = {"camera buffers", 2, 32, "", ""};

// Profile files: bigger ones are refused before parsing (the board a profile targets has little
// memory), and at most this many errors are printed, then a count of the rest.
inline constexpr size_t kMaxProfileBytes = 1 << 20;  // 1 MiB
inline constexpr size_t kMaxPrintedErrors = 50;

// "16..4096 pixels per side", "0..256 (0: one per CPU)".
std::string RangeText(const IntRange& range);
bool InRange(const IntRange& range, long long value);

// "" when `value` is in range, else "<flag>: <value> is outside the <what> limits <range>".
std::string CheckRange(const IntRange& range, const std::string& flag, long long value);
// "" when both sides are in kInputSide (or `range`), else
// "<flag>: 5000x96 (HxW) is outside the input size limits 16..4096 pixels per side".
std::string CheckSize(const IntRange& range, const std::string& flag, long long height,
                      long long width);

// A real number as sfrt reads one wherever a user writes it (command-line options, profile
// fields, node parameters): the whole text in strtod's syntax, and finite: "nan", "inf" and
// values beyond double's range are refused, so no NaN can pass a range check or mean "none".
bool ParseFiniteNumber(const std::string& text, double* value);

// 0 -> the number of CPUs (at least 1); anything else unchanged.
int ResolveThreads(int threads);

// The table as Markdown rows "| what | lo..hi | unit / note |", one per limit, for docs and for
// the test that keeps firmware-cfg/README.md in step.
std::vector<std::string> LimitsMarkdownRows();

}  // namespace sfrt::config
