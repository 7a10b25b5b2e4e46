#include "eval/conventions.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>

#include "eval/metrics.h"

namespace sfrt::eval {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string Number(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

const char* Operator(Compare compare) {
  switch (compare) {
    case Compare::kBelow:
      return "<";
    case Compare::kAtMost:
      return "<=";
    case Compare::kAbove:
      return ">";
  }
  return "?";
}

bool Passes(Compare compare, double value, double threshold) {
  switch (compare) {
    case Compare::kBelow:
      return value < threshold;
    case Compare::kAtMost:
      return value <= threshold;
    case Compare::kAbove:
      return value > threshold;
  }
  return false;
}

// EPE, and EPE / (|g| + epsilon) (+infinity where that is 0 and EPE > 0), of one pixel.
struct PixelError {
  double epe;
  double relative;
};

PixelError ErrorAt(const float* pred, const float* g, double epsilon) {
  double sum = 0;
  bool finite = true;
  for (int c = 0; c < 3; ++c) {
    const double p = pred == nullptr ? 0.0 : static_cast<double>(pred[c]);
    if (!std::isfinite(p)) finite = false;
    const double d = p - static_cast<double>(g[c]);
    sum += d * d;
  }
  const double epe = finite ? std::sqrt(sum) : kInf;
  const double norm =
      std::sqrt(static_cast<double>(g[0]) * g[0] + static_cast<double>(g[1]) * g[1] +
                static_cast<double>(g[2]) * g[2]) +
      epsilon;
  return {epe, norm > 0 ? epe / norm : (epe > 0 ? kInf : 0.0)};
}

}  // namespace

bool ShareTest::Counts(double epe_value, double relative_value) const {
  return Passes(compare, epe_value, epe) ||
         (relative > 0 && Passes(compare, relative_value, relative));
}

std::string ShareTest::Definition(double relative_epsilon) const {
  if (column == nullptr) return "not reported";
  const std::string op = Operator(compare);
  std::string text = std::string(column) + ": EPE " + op + " " + Number(epe);
  if (relative > 0) {
    const std::string norm =
        relative_epsilon > 0 ? "(|gt|+" + Number(relative_epsilon) + ")" : "|gt|";
    text += " or EPE/" + norm + " " + op + " " + Number(relative * 100) + "%";
  }
  return text;
}

std::string Convention::MaskWords() const {
  std::string words;
  for (int i = 0; i < kMaskInputs; ++i) {
    if (below[static_cast<size_t>(i)] <= 0) continue;
    words += (words.empty() ? "" : " and ") + std::string(kMaskInputNames[static_cast<size_t>(i)]) +
             " < " + Number(below[static_cast<size_t>(i)]) +
             kMaskInputUnits[static_cast<size_t>(i)];
  }
  return words.empty() ? "every pixel" : words;
}

std::string Convention::Definition() const {
  std::string text = std::string(name) + ": pixels with " + MaskWords() + "; EPE3D";
  for (int s = 0; s < kConventionShares; ++s) {
    text += std::string("; ") + kShareRules[s].key + " = " +
            shares[static_cast<size_t>(s)].Definition(relative_epsilon);
  }
  text += averaging == Averaging::kPerFrame ? "; each frame's means, averaged over the frames"
                                            : "; means over all kept pixels of all frames";
  return text + " (" + source + ")";
}

bool ConventionAccumulator::Keeps(const MaskInputs& inputs, size_t pixel) const {
  const Convention& c = convention();
  for (size_t i = 0; i < kMaskInputs; ++i) {
    // NaN and infinity (no depth) fail the comparison: the pixel is dropped.
    if (c.below[i] > 0 && !(inputs.values[i][pixel] < c.below[i])) return false;
  }
  return true;
}

void ConventionAccumulator::Add(const float* pred, const float* truth, const MaskInputs& inputs,
                                size_t pixels) {
  if (!unavailable_.empty()) return;
  const Convention& c = convention();
  for (size_t i = 0; i < kMaskInputs; ++i) {
    if (c.below[i] > 0 && inputs.values[i] == nullptr) {
      MarkUnavailable(std::string("its mask needs the ") + kMaskInputNames[i] + ": " +
                      inputs.missing[i]);
      return;
    }
  }
  double frame_epe = 0;
  std::array<uint64_t, kConventionShares> frame_counts{};
  uint64_t kept = 0;
  for (size_t p = 0; p < pixels; ++p) {
    const float* g = truth + 3 * p;
    if (!std::isfinite(g[0]) || !std::isfinite(g[1]) || !std::isfinite(g[2])) continue;
    if (!Keeps(inputs, p)) continue;
    const PixelError e = ErrorAt(pred == nullptr ? nullptr : pred + 3 * p, g, c.relative_epsilon);
    frame_epe += e.epe;
    for (size_t s = 0; s < kConventionShares; ++s) {
      if (c.shares[s].column != nullptr && c.shares[s].Counts(e.epe, e.relative)) {
        ++frame_counts[s];
      }
    }
    ++kept;
  }
  sum_epe_ += frame_epe;
  pixels_ += kept;
  for (size_t s = 0; s < kConventionShares; ++s) counts_[s] += frame_counts[s];
  if (kept == 0) return;
  const double n = static_cast<double>(kept);
  frame_epe_ += frame_epe / n;
  for (size_t s = 0; s < kConventionShares; ++s) {
    frame_shares_[s] += static_cast<double>(frame_counts[s]) / n;
  }
  ++frames_;
}

void ConventionAccumulator::MarkUnavailable(const std::string& reason) {
  if (unavailable_.empty()) unavailable_ = reason;
}

void ConventionAccumulator::Merge(const ConventionAccumulator& other) {
  MarkUnavailable(other.unavailable_);
  sum_epe_ += other.sum_epe_;
  pixels_ += other.pixels_;
  frame_epe_ += other.frame_epe_;
  frames_ += other.frames_;
  for (size_t s = 0; s < kConventionShares; ++s) {
    counts_[s] += other.counts_[s];
    frame_shares_[s] += other.frame_shares_[s];
  }
}

ConventionMetrics ConventionAccumulator::Metrics() const {
  ConventionMetrics m;
  m.available = unavailable_.empty();
  m.unavailable = unavailable_;
  m.valid_pixels = pixels_;
  m.frames = frames_;
  const Convention& c = convention();
  const bool per_frame = c.averaging == Averaging::kPerFrame;
  const double n = static_cast<double>(per_frame ? frames_ : pixels_);
  for (size_t s = 0; s < kConventionShares; ++s) {
    // A share the paper does not report stays NaN (null in the JSON, "-" in the table).
    m.shares[s] = std::numeric_limits<double>::quiet_NaN();
  }
  if (!m.available || n == 0) {
    for (size_t s = 0; s < kConventionShares; ++s) {
      if (c.shares[s].column != nullptr) m.shares[s] = 0;
    }
    return m;
  }
  m.epe3d = (per_frame ? frame_epe_ : sum_epe_) / n;
  for (size_t s = 0; s < kConventionShares; ++s) {
    if (c.shares[s].column == nullptr) continue;
    m.shares[s] = (per_frame ? frame_shares_[s] : static_cast<double>(counts_[s])) / n;
  }
  return m;
}

nlohmann::json ConventionAccumulator::State() const {
  if (!unavailable_.empty()) return {{"unavailable", unavailable_}};
  nlohmann::json s;
  s["sum_epe"] = ExactDouble(sum_epe_);
  s["counts"] = counts_;
  s["pixels"] = pixels_;
  s["frame_epe"] = ExactDouble(frame_epe_);
  s["frame_shares"] = nlohmann::json::array();
  for (double v : frame_shares_) s["frame_shares"].push_back(ExactDouble(v));
  s["frames"] = frames_;
  return s;
}

Result<ConventionAccumulator> ConventionAccumulator::FromState(const nlohmann::json& s,
                                                               int convention) {
  ConventionAccumulator a(convention);
  if (!s.is_object()) return Status::Error("convention state: expected an object");
  if (s.contains("unavailable")) {
    if (!s["unavailable"].is_string() || s["unavailable"].get<std::string>().empty()) {
      return Status::Error("unavailable: expected the reason");
    }
    a.unavailable_ = s["unavailable"].get<std::string>();
    return a;
  }
  Result<double> sum = ReadExactDouble(s.value("sum_epe", nlohmann::json()), "sum_epe");
  if (!sum.ok()) return sum.status();
  Result<double> frame_sum = ReadExactDouble(s.value("frame_epe", nlohmann::json()), "frame_epe");
  if (!frame_sum.ok()) return frame_sum.status();
  a.sum_epe_ = *sum;
  a.frame_epe_ = *frame_sum;
  for (auto [key, target] : {std::pair{"pixels", &a.pixels_}, std::pair{"frames", &a.frames_}}) {
    Result<uint64_t> n = ReadCount(s, key);
    if (!n.ok()) return n.status();
    *target = *n;
  }
  const nlohmann::json counts = s.value("counts", nlohmann::json());
  const nlohmann::json shares = s.value("frame_shares", nlohmann::json());
  if (!counts.is_array() || counts.size() != kConventionShares || !shares.is_array() ||
      shares.size() != kConventionShares) {
    return Status::Error("counts, frame_shares: expected 3 each");
  }
  for (size_t k = 0; k < kConventionShares; ++k) {
    if (!counts[k].is_number_unsigned()) return Status::Error("counts: expected counts");
    a.counts_[k] = counts[k].get<uint64_t>();
    Result<double> v = ReadExactDouble(shares[k], "frame_shares");
    if (!v.ok()) return v.status();
    a.frame_shares_[k] = *v;
  }
  return a;
}

ConventionSet::ConventionSet() {
  for (int c = 0; c < kConventionCount; ++c)
    rows_[static_cast<size_t>(c)] = ConventionAccumulator(c);
}

void ConventionSet::Add(const float* pred, const float* truth, const MaskInputs& inputs,
                        size_t pixels) {
  for (ConventionAccumulator& row : rows_) row.Add(pred, truth, inputs, pixels);
}

void ConventionSet::Merge(const ConventionSet& other) {
  for (size_t c = 0; c < rows_.size(); ++c) rows_[c].Merge(other.rows_[c]);
}

nlohmann::json ConventionSet::State() const {
  nlohmann::json s = nlohmann::json::object();
  for (const ConventionAccumulator& row : rows_) s[row.convention().key] = row.State();
  return s;
}

Result<ConventionSet> ConventionSet::FromState(const nlohmann::json& state) {
  ConventionSet set;
  for (int c = 0; c < kConventionCount; ++c) {
    const char* key = kConventions[c].key;
    if (!state.is_object() || !state.contains(key)) {
      return Status::Error(std::string("conventions: no ") + key);
    }
    Result<ConventionAccumulator> row = ConventionAccumulator::FromState(state[key], c);
    if (!row.ok()) return Status::Error(std::string("conventions ") + key + ": " + row.message());
    set.rows_[static_cast<size_t>(c)] = *row;
  }
  return set;
}

}  // namespace sfrt::eval
