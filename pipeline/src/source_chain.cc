#include "sfrt/pipeline/source_chain.h"

#include <nlohmann/json.hpp>
#include <utility>

namespace sfrt::pipeline {
namespace {

std::string SizeText(const cv::Size& s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width);
}

class SourceChain final : public FrameSource {
 public:
  SourceChain(std::vector<SourceUnit> units, std::string description, std::string kind)
      : units_(std::move(units)), description_(std::move(description)), kind_(std::move(kind)) {}

  Result<cv::Size> Open() override {
    if (units_.empty()) return Status::Error(description_ + ": no unit to replay");
    Result<cv::Size> size = OpenUnit(0);
    if (size.ok()) size_ = *size;
    return size;
  }

  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override {
    while (current_) {
      Result<Fetch> next = current_->Next(item, stop);
      if (!next.ok() || *next == Fetch::kWindow) {
        if (next.ok()) item->meta.sequence = units_[index_].name;
        return next;
      }
      Retire();
      if (index_ + 1 >= units_.size() || stop.load()) return Fetch::kEnd;
      Result<cv::Size> size = OpenUnit(index_ + 1);
      if (!size.ok()) return size.status();
      if (*size != size_) {
        return Status::Error(units_[index_].name + ": its images are " + SizeText(*size) +
                             " (HxW) but " + units_[0].name + "'s are " + SizeText(size_) +
                             "; replay units of one size together");
      }
    }
    return Fetch::kEnd;
  }

  std::string Describe() const override { return description_; }
  std::string kind() const override { return kind_; }
  bool live() const override { return false; }
  uint64_t drops() const override { return drops_ + (current_ ? current_->drops() : 0); }
  std::vector<BadFrame> bad_frames() const override {
    std::vector<BadFrame> all = bad_;
    if (current_) Append(current_->bad_frames(), index_, &all);
    return all;
  }
  camera::ChainCounts chain_counts() const override {
    camera::ChainCounts c = chain_;
    if (current_) c += current_->chain_counts();
    return c;
  }
  void ToJson(nlohmann::json* out) const override {
    nlohmann::json units = units_json_;
    if (current_) units.push_back(UnitJson(*current_, index_));
    (*out)["units"] = units;
  }

 private:
  Result<cv::Size> OpenUnit(size_t i) {
    index_ = i;
    current_ = units_[i].make();
    current_->set_log(&log());
    return current_->Open();
  }

  // The finished unit's counters and facts, kept; its source closed.
  void Retire() {
    drops_ += current_->drops();
    chain_ += current_->chain_counts();
    Append(current_->bad_frames(), index_, &bad_);
    units_json_.push_back(UnitJson(*current_, index_));
    current_.reset();
  }

  void Append(const std::vector<BadFrame>& bad, size_t unit, std::vector<BadFrame>* all) const {
    for (BadFrame b : bad) {
      b.sequence = units_[unit].name;
      all->push_back(std::move(b));
    }
  }

  nlohmann::json UnitJson(const FrameSource& source, size_t unit) const {
    nlohmann::json j = {{"sequence", units_[unit].name}};
    source.ToJson(&j);
    return j;
  }

  std::vector<SourceUnit> units_;
  std::string description_;
  std::string kind_;
  cv::Size size_;
  size_t index_ = 0;
  std::unique_ptr<FrameSource> current_;
  // The units before the current one.
  uint64_t drops_ = 0;
  camera::ChainCounts chain_;
  std::vector<BadFrame> bad_;
  nlohmann::json units_json_ = nlohmann::json::array();
};

}  // namespace

std::unique_ptr<FrameSource> MakeSourceChain(std::vector<SourceUnit> units, std::string description,
                                             std::string kind) {
  return std::make_unique<SourceChain>(std::move(units), std::move(description), std::move(kind));
}

}  // namespace sfrt::pipeline
