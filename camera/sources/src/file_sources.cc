// File-backed stereo sources: dataset layouts (Scene Flow, KITTI, stereo directories) and plain
// directory / glob pairs. All of them resolve to a list of (left path, right path) entries at open
// time and share one reader.
#include <glob.h>

#include <algorithm>
#include <cctype>
#include <exception>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <system_error>
#include <utility>

#include "sfrt/camera/image_file.h"
#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

namespace fs = std::filesystem;

constexpr int kMaxDepth = 8;

struct Entry {
  std::string sequence;
  int64_t frame_number = -1;
  std::string left_path;       // empty: no left frame at this position
  std::string right_path;      // empty: no right frame at this position
  std::string missing_reason;  // for an empty side: why there is no partner
};

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool IsImageName(const fs::path& p) {
  static const std::set<std::string> kExt = {".png", ".jpg", ".jpeg", ".ppm", ".pgm",
                                             ".bmp", ".tif", ".tiff", ".webp"};
  return kExt.count(Lower(p.extension().string())) > 0;
}

// Trailing digits of the file stem: "0006" -> 6, "000042_11" -> 11, "img" -> -1.
int64_t TrailingNumber(const std::string& stem) {
  size_t end = stem.size();
  size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end || end - begin > 18) return -1;
  return std::stoll(stem.substr(begin, end - begin));
}

bool IsDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

// Image file names (not paths) directly in dir, sorted by byte order.
Result<std::vector<std::string>> ListImages(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  if (ec) return Status::Error(dir.string() + ": cannot list directory (" + ec.message() + ")");
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return Status::Error(dir.string() + ": cannot list directory (" + ec.message() + ")");
    std::error_code type_ec;
    if (IsImageName(it->path()) && !it->is_directory(type_ec)) {
      names.push_back(it->path().filename().string());
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

bool HasImages(const fs::path& dir) {
  if (!IsDir(dir)) return false;
  Result<std::vector<std::string>> names = ListImages(dir);
  return names.ok() && !names->empty();
}

// Pairs left/ and right/ of one sequence directory by identical file name.
Status AddStereoDirSequence(const fs::path& seq_dir, const std::string& sequence,
                            std::vector<Entry>* entries) {
  Result<std::vector<std::string>> left = ListImages(seq_dir / "left");
  if (!left.ok()) return left.status();
  Result<std::vector<std::string>> right = ListImages(seq_dir / "right");
  if (!right.ok()) return right.status();
  std::set<std::string> names(left->begin(), left->end());
  names.insert(right->begin(), right->end());
  const std::set<std::string> left_set(left->begin(), left->end());
  const std::set<std::string> right_set(right->begin(), right->end());
  for (const std::string& name : names) {
    Entry e;
    e.sequence = sequence;
    e.frame_number = TrailingNumber(fs::path(name).stem().string());
    e.left_path = (seq_dir / "left" / name).string();
    e.right_path = (seq_dir / "right" / name).string();
    if (!left_set.count(name)) {
      e.missing_reason = "left:missing (the right frame " + e.right_path + " has no left partner)";
    } else if (!right_set.count(name)) {
      e.missing_reason = "right:missing (the left frame " + e.left_path + " has no right partner)";
    }
    entries->push_back(std::move(e));
  }
  return Status::Ok();
}

void FindStereoDirs(const fs::path& dir, int depth, std::vector<fs::path>* found) {
  if (HasImages(dir / "left") && HasImages(dir / "right")) {
    found->push_back(dir);
    return;
  }
  if (depth >= kMaxDepth) return;
  std::vector<fs::path> children;
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  if (ec) return;
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) break;
    std::error_code type_ec;
    if (it->is_directory(type_ec)) children.push_back(it->path());
  }
  std::sort(children.begin(), children.end());
  for (const fs::path& child : children) FindStereoDirs(child, depth + 1, found);
}

bool PathHasComponent(const fs::path& p, const std::string& name) {
  for (const fs::path& part : p) {
    if (part == name) return true;
  }
  return false;
}

// KITTI: image_2/NNNNNN_KK.png with image_3/ beside it.
Status AddKittiSplit(const fs::path& split_dir, const std::string& split_name,
                     std::vector<Entry>* entries, std::vector<std::string>* sequences) {
  Result<std::vector<std::string>> left = ListImages(split_dir / "image_2");
  if (!left.ok()) return left.status();
  Result<std::vector<std::string>> right = ListImages(split_dir / "image_3");
  if (!right.ok()) return right.status();
  // scene -> (frame number -> file name)
  std::map<std::string, std::map<int64_t, std::string>> scenes;
  std::set<std::string> left_set(left->begin(), left->end());
  std::set<std::string> right_set(right->begin(), right->end());
  std::set<std::string> names = left_set;
  names.insert(right->begin(), right->end());
  for (const std::string& name : names) {
    const std::string stem = fs::path(name).stem().string();
    const size_t underscore = stem.rfind('_');
    std::string scene = stem;
    int64_t frame = -1;
    if (underscore != std::string::npos) {
      scene = stem.substr(0, underscore);
      frame = TrailingNumber(stem.substr(underscore + 1));
    }
    scenes[scene][frame] = name;
  }
  for (const auto& [scene, frames] : scenes) {
    const std::string sequence = split_name.empty() ? scene : split_name + "/" + scene;
    sequences->push_back(sequence);
    for (const auto& [frame, name] : frames) {
      Entry e;
      e.sequence = sequence;
      e.frame_number = frame;
      e.left_path = (split_dir / "image_2" / name).string();
      e.right_path = (split_dir / "image_3" / name).string();
      if (!left_set.count(name)) {
        e.missing_reason =
            "left:missing (the right frame " + e.right_path + " has no left partner)";
      } else if (!right_set.count(name)) {
        e.missing_reason =
            "right:missing (the left frame " + e.left_path + " has no right partner)";
      }
      entries->push_back(std::move(e));
    }
  }
  return Status::Ok();
}

Result<std::vector<std::string>> ResolveSpec(const std::string& spec) {
  if (spec.find_first_of("*?[") != std::string::npos) {
    glob_t g{};
    const int rc = glob(spec.c_str(), 0, nullptr, &g);
    std::vector<std::string> paths;
    if (rc == 0) {
      for (size_t i = 0; i < g.gl_pathc; ++i) paths.emplace_back(g.gl_pathv[i]);
    }
    globfree(&g);
    if (rc == GLOB_NOMATCH) return Status::Error("glob '" + spec + "' matches no file");
    if (rc != 0) return Status::Error("glob '" + spec + "' failed (read error or out of memory)");
    std::sort(paths.begin(), paths.end(), [](const std::string& a, const std::string& b) {
      return fs::path(a).filename().string() < fs::path(b).filename().string() ||
             (fs::path(a).filename() == fs::path(b).filename() && a < b);
    });
    return paths;
  }
  if (!IsDir(spec)) {
    return Status::Error("'" + spec + "' is neither a directory nor a glob pattern (* ? [)");
  }
  Result<std::vector<std::string>> names = ListImages(spec);
  if (!names.ok()) return names.status();
  if (names->empty()) return Status::Error(spec + ": no image files in this directory");
  std::vector<std::string> paths;
  for (const std::string& n : *names) paths.push_back((fs::path(spec) / n).string());
  return paths;
}

// Reads one image as 8-bit BGR; empty string when fine, otherwise the reason.
// `decoded` counts the images handed to the decoder.
std::string ReadImage(const std::string& path, cv::Mat* out, uint64_t* decoded) {
  if (std::string why = ReadImageFile(path, cv::IMREAD_COLOR, out, decoded); !why.empty()) {
    return why;
  }
  if (out->type() != CV_8UC3) return "did not decode to 8-bit BGR";
  return "";
}

class FileListSource final : public StereoSource {
 public:
  FileListSource(std::vector<Entry> entries, std::string description, SourceOptions options)
      : entries_(std::move(entries)),
        description_(std::move(description)),
        options_(std::move(options)) {}

  Result<Fetched> Next(FramePair* pair) override {
    if (!stopped_.ok()) return stopped_;
    while (next_ < entries_.size()) {
      const int64_t index = static_cast<int64_t>(next_);
      const Entry& e = entries_[next_++];
      BadFrame bad;
      bad.index = index;
      bad.sequence = e.sequence;
      if (!e.missing_reason.empty()) {
        const bool left_side = e.missing_reason.rfind("left:", 0) == 0;
        bad.path = left_side ? e.left_path : e.right_path;
        bad.reason = e.missing_reason.substr(e.missing_reason.find(':') + 1);
      } else if (std::string why = ReadImage(e.left_path, &pair->left, &images_decoded_);
                 !why.empty()) {
        bad = {e.left_path, why, index, e.sequence};
      } else if (std::string why_r = ReadImage(e.right_path, &pair->right, &images_decoded_);
                 !why_r.empty()) {
        bad = {e.right_path, why_r, index, e.sequence};
      } else if (pair->left.size() != pair->right.size()) {
        bad = {e.right_path,
               "is " + std::to_string(pair->right.rows) + "x" + std::to_string(pair->right.cols) +
                   " (HxW) but its left frame " + e.left_path + " is " +
                   std::to_string(pair->left.rows) + "x" + std::to_string(pair->left.cols),
               index, e.sequence};
      }
      if (!bad.path.empty()) {
        if (options_.on_bad_frame == BadFramePolicy::kStop) {
          stopped_ = Status::Error("bad frame " + bad.path + ": " + bad.reason);
          return stopped_;
        }
        skipped_.push_back(bad);
        if (options_.on_bad_frame_callback) options_.on_bad_frame_callback(bad);
        continue;
      }
      pair->index = index;
      pair->sequence = e.sequence;
      pair->frame_number = e.frame_number;
      pair->timestamp_s.reset();
      pair->left_path = e.left_path;
      pair->right_path = e.right_path;
      return Fetched::kPair;
    }
    return Fetched::kEnd;
  }

  std::string Describe() const override { return description_; }
  std::optional<int64_t> size() const override { return static_cast<int64_t>(entries_.size()); }

 private:
  std::vector<Entry> entries_;
  std::string description_;
  SourceOptions options_;
  size_t next_ = 0;
  Status stopped_;
};

struct Detected {
  DatasetInfo info;
  std::vector<Entry> entries;
};

// Keeps the sequences `wanted` names (all when empty), in the dataset's order; the counts before
// the selection go to all_sequences and all_pairs.
Status SelectSequences(const std::vector<std::string>& wanted, Detected* d) {
  d->info.all_sequences = d->info.sequences.size();
  d->info.all_pairs = static_cast<int64_t>(d->entries.size());
  d->info.pairs = d->info.all_pairs;
  if (wanted.empty()) return Status::Ok();
  const std::set<std::string> keep(wanted.begin(), wanted.end());
  for (const std::string& name : keep) {
    if (std::find(d->info.sequences.begin(), d->info.sequences.end(), name) ==
        d->info.sequences.end()) {
      return Status::Error("dataset root '" + d->info.root + "' has no sequence '" + name + "'");
    }
  }
  std::erase_if(d->info.sequences, [&](const std::string& s) { return !keep.count(s); });
  std::erase_if(d->entries, [&](const Entry& e) { return !keep.count(e.sequence); });
  d->info.pairs = static_cast<int64_t>(d->entries.size());
  return Status::Ok();
}

Result<Detected> DetectAll(const std::string& root, const DatasetOptions& options) {
  if (!IsDir(root)) return Status::Error("dataset root '" + root + "' is not a directory");
  if (options.pass != "clean" && options.pass != "final") {
    return Status::Error("dataset pass '" + options.pass + "' is neither clean nor final");
  }
  Detected d;
  d.info.root = root;
  const fs::path r(root);

  // 1. KITTI.
  std::vector<std::pair<fs::path, std::string>> kitti_splits;
  if (IsDir(r / "image_2") && IsDir(r / "image_3")) {
    kitti_splits.emplace_back(r, "");
  } else {
    for (const char* split : {"training", "testing"}) {
      if (IsDir(r / split / "image_2") && IsDir(r / split / "image_3")) {
        kitti_splits.emplace_back(r / split, split);
      }
    }
  }
  if (!kitti_splits.empty()) {
    d.info.layout = DatasetLayout::kKitti;
    for (const auto& [dir, name] : kitti_splits) {
      if (Status s = AddKittiSplit(dir, name, &d.entries, &d.info.sequences); !s.ok()) return s;
    }
    if (d.entries.empty()) {
      return Status::Error(root + ": KITTI layout (image_2, image_3) but no image files in it");
    }
    return d;
  }

  // 2. Directories holding left/ and right/.
  std::vector<fs::path> dirs;
  FindStereoDirs(r, 0, &dirs);
  bool has_clean = false;
  bool has_final = false;
  for (const fs::path& dir : dirs) {
    has_clean = has_clean || PathHasComponent(dir, "frames_cleanpass");
    has_final = has_final || PathHasComponent(dir, "frames_finalpass");
  }
  std::string skip_pass;
  if (has_clean || has_final) {
    d.info.layout = DatasetLayout::kSceneFlow;
    if (has_clean && has_final) {
      d.info.pass = options.pass == "final" ? "finalpass" : "cleanpass";
    } else {
      d.info.pass = has_clean ? "cleanpass" : "finalpass";
    }
    skip_pass = d.info.pass == "cleanpass" ? "frames_finalpass" : "frames_cleanpass";
  }
  for (const fs::path& dir : dirs) {
    if (!skip_pass.empty() && PathHasComponent(dir, skip_pass)) continue;
    std::string sequence = fs::relative(dir, r).generic_string();
    if (sequence == ".") sequence = r.filename().string();
    if (sequence.empty()) sequence = r.parent_path().filename().string();
    d.info.sequences.push_back(sequence);
    if (Status s = AddStereoDirSequence(dir, sequence, &d.entries); !s.ok()) return s;
  }
  if (d.entries.empty()) {
    return Status::Error(
        "dataset root '" + root +
        "': no known layout (no image_2/ + image_3/ for KITTI, and no directory within 8 levels "
        "holding left/ and right/ with image files)");
  }
  return d;
}

Result<Detected> Detect(const std::string& root, const DatasetOptions& options) {
  Result<Detected> d = DetectAll(root, options);
  if (!d.ok()) return d;
  if (Status s = SelectSequences(options.sequences, &*d); !s.ok()) return s;
  return d;
}

}  // namespace

Result<BadFramePolicy> ParseBadFramePolicy(const std::string& text) {
  if (const std::optional<BadFramePolicy> p = vocabulary::FailurePolicyFromName(text)) return *p;
  return Status::Error("bad-frame policy '" + text + "' is neither skip nor stop");
}

const char* DatasetLayoutName(DatasetLayout layout) {
  switch (layout) {
    case DatasetLayout::kSceneFlow:
      return "Scene Flow";
    case DatasetLayout::kStereoDirs:
      return "stereo directories";
    case DatasetLayout::kKitti:
      return "KITTI";
  }
  return "unknown";
}

Result<DatasetInfo> DetectDataset(const std::string& root, const DatasetOptions& options) {
  Result<Detected> d = Detect(root, options);
  if (!d.ok()) return d.status();
  return std::move(d->info);
}

Result<std::unique_ptr<StereoSource>> OpenDatasetSource(const std::string& root,
                                                        const DatasetOptions& options) {
  Result<Detected> d = Detect(root, options);
  if (!d.ok()) return d.status();
  std::string description = DescribeDataset(d->info);
  std::unique_ptr<StereoSource> source = std::make_unique<FileListSource>(
      std::move(d->entries), std::move(description), static_cast<const SourceOptions&>(options));
  return source;
}

std::string DescribeDataset(const DatasetInfo& info) {
  const size_t n = info.sequences.size();
  const bool selected = n != info.all_sequences;
  std::string d = std::string(DatasetLayoutName(info.layout)) + " dataset " + info.root + " (";
  if (!info.pass.empty()) d += "frames_" + info.pass + ", ";
  d += std::to_string(n) + (selected ? " of " + std::to_string(info.all_sequences) : "") +
       " sequence" + ((selected ? info.all_sequences : n) == 1 ? "" : "s") + ", " +
       std::to_string(info.pairs) + (selected ? " of " + std::to_string(info.all_pairs) : "") +
       " pairs)";
  return d;
}

Result<DatasetInfo> DetectDataset(const std::string& root) {
  return DetectDataset(root, DatasetOptions());
}

Result<std::unique_ptr<StereoSource>> OpenDatasetSource(const std::string& root) {
  return OpenDatasetSource(root, DatasetOptions());
}

Result<std::vector<std::string>> ListFrameFiles(const std::string& spec) {
  return ResolveSpec(spec);
}

Result<std::unique_ptr<StereoSource>> OpenPlainSource(const std::string& left_spec,
                                                      const std::string& right_spec) {
  return OpenPlainSource(left_spec, right_spec, SourceOptions());
}

Result<std::unique_ptr<StereoSource>> OpenPlainSource(const std::string& left_spec,
                                                      const std::string& right_spec,
                                                      const SourceOptions& options) {
  Result<std::vector<std::string>> left = ResolveSpec(left_spec);
  if (!left.ok()) return Status::Error("left frames: " + left.message());
  Result<std::vector<std::string>> right = ResolveSpec(right_spec);
  if (!right.ok()) return Status::Error("right frames: " + right.message());
  const size_t n = std::max(left->size(), right->size());
  std::vector<Entry> entries(n);
  for (size_t i = 0; i < n; ++i) {
    Entry& e = entries[i];
    e.frame_number = static_cast<int64_t>(i);
    if (i < left->size()) e.left_path = (*left)[i];
    if (i < right->size()) e.right_path = (*right)[i];
    if (i >= right->size()) {
      e.right_path = e.left_path;  // the path reported is the frame without a partner
      e.missing_reason = "right:no right frame at position " + std::to_string(i) + " (" +
                         right_spec + " has " + std::to_string(right->size()) + " images, " +
                         left_spec + " has " + std::to_string(left->size()) + ")";
    } else if (i >= left->size()) {
      e.left_path = e.right_path;
      e.missing_reason = "left:no left frame at position " + std::to_string(i) + " (" + left_spec +
                         " has " + std::to_string(left->size()) + " images, " + right_spec +
                         " has " + std::to_string(right->size()) + ")";
    }
  }
  std::string description =
      "frame pairs " + left_spec + " | " + right_spec + " (" + std::to_string(n) + " pairs)";
  std::unique_ptr<StereoSource> source =
      std::make_unique<FileListSource>(std::move(entries), std::move(description), options);
  return source;
}

Result<Fetched> PairWindow::Next() {
  while (true) {
    const int free_slot = have_current_ ? 1 - current_slot_ : current_slot_;
    Result<Fetched> got = source_->Next(&slots_[free_slot]);
    if (!got.ok() || *got == Fetched::kEnd) return got;
    const FramePair& fresh = slots_[free_slot];
    if (!have_current_ || fresh.sequence != current().sequence) {
      chain_.Restart();
    } else if (fresh.index != current().index + 1) {
      chain_.Lose();  // the pairs between were skipped (bad frames)
    }
    // Frame numbers, not video timestamps (some backends report none or zeros); a name without
    // digits has none, and its place in the listing stands in.
    const int64_t stamp = fresh.frame_number >= 0 ? fresh.frame_number : fresh.index;
    current_slot_ = free_slot;
    have_current_ = true;
    if (chain_.Offer(stamp) == ChainLink::kWindow) return Fetched::kPair;
  }
}

}  // namespace sfrt::camera
