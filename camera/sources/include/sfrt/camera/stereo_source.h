// Stereo frame-pair sources from files: Scene Flow datasets, KITTI scene flow, two plain
// directories or glob patterns, and side-by-side stereo video files.
//
// Every source hands out stereo pairs as stored (rectify with rectifier.h) through Next().
// SceneEDNet consumes two consecutive pairs (t, t+1); PairWindow turns a source into those
// windows without ever pairing across a sequence boundary or across a skipped frame.
//
// Ownership: the factories return a std::unique_ptr the caller owns. Next() writes into the
// caller's FramePair; the images are 8-bit 3-channel BGR (CV_8UC3). A source may reuse the
// memory behind pair.left / pair.right when their size and type already match, so clone an image
// you keep past the next call with the same FramePair. The video source does: in steady state
// its Next() allocates nothing beyond what OpenCV's decoder allocates per frame (FFmpeg's packets
// and frame pool; one image with OpenCV's own MJPEG backend) (camera_video_allocation_test).
//
// Thread-safety: a source is not thread-safe; call it from one thread (it may be moved between
// threads). Different sources are independent.
//
// Error policy: opening validates the layout and fails with a one-line Status naming the path
// and what is wrong (no images found, unknown layout, unreadable directory). A bad frame (file
// missing, unreadable, not decodable, left/right sizes differ) is named by path: under
// BadFramePolicy::kStop, Next() returns that error and the source stays stopped (every later call
// returns the same error); under kSkip it is recorded in skipped(), passed to on_bad_frame, and
// Next() moves on to the following pair.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/camera/status.h"
#include "sfrt/camera/window_chain.h"
#include "sfrt/vocabulary/failure_policy.h"

namespace sfrt::camera {

struct FramePair {
  cv::Mat left;   // CV_8UC3, BGR
  cv::Mat right;  // CV_8UC3, BGR, same size as left
  // Position in the source's enumeration, counting skipped pairs too: two pairs are consecutive
  // exactly when their indices differ by one and their sequence names match.
  int64_t index = -1;
  // Sequence the pair belongs to ("" for single-sequence sources). Scene Flow: the directory
  // holding left/ and right/, relative to the root; KITTI: "<split>/<scene number>".
  std::string sequence;
  // The frame's own number: the trailing digits of the file name (0006 -> 6, 000042_11 -> 11),
  // the position in the sorted list for plain directories, or the video frame number.
  int64_t frame_number = -1;
  // Seconds since the start of the stream, when the source knows it (video files).
  std::optional<double> timestamp_s;
  // Where the images came from; for video: "<file>#<frame number>" with "(left half)" and
  // "(right half)" suffixes.
  std::string left_path;
  std::string right_path;
};

using BadFramePolicy = vocabulary::FailurePolicy;  // kSkip, kStop

struct BadFrame {
  std::string path;        // the file at fault (for a left/right size mismatch: the right file)
  std::string reason;      // one line, e.g. "missing", "could not be decoded as an image"
  int64_t index = -1;      // FramePair::index the bad pair would have had
  std::string sequence{};  // FramePair::sequence of the bad pair ("" for single-sequence sources)
};

// "skip" / "stop" (as `--on-bad-frame` and profiles' `on_bad_frame` spell them); the error
// names the text.
Result<BadFramePolicy> ParseBadFramePolicy(const std::string& text);
constexpr const char* BadFramePolicyName(BadFramePolicy policy) {
  return vocabulary::FailurePolicyName(policy);
}

struct SourceOptions {
  BadFramePolicy on_bad_frame = BadFramePolicy::kStop;
  // Called (on the thread calling Next) for each bad frame skipped under kSkip.
  std::function<void(const BadFrame&)> on_bad_frame_callback;
};

enum class Fetched { kPair, kEnd };

class StereoSource {
 public:
  virtual ~StereoSource() = default;
  StereoSource() = default;
  StereoSource(const StereoSource&) = delete;
  StereoSource& operator=(const StereoSource&) = delete;

  // Reads the next pair into *pair. kPair: *pair holds it; kEnd: the source is exhausted (and
  // stays so). Error: a bad frame under kStop, or a failure of the underlying reader.
  virtual Result<Fetched> Next(FramePair* pair) = 0;
  // One line for logs, e.g. "Scene Flow dataset /data/Driving (frames_cleanpass, 4 sequences)".
  virtual std::string Describe() const = 0;
  // Number of pairs the source will enumerate (including bad ones), when known up front.
  virtual std::optional<int64_t> size() const = 0;
  // Bad frames skipped so far under BadFramePolicy::kSkip, in order.
  const std::vector<BadFrame>& skipped() const { return skipped_; }
  // Images decoded so far: two per pair of image files (one per video frame); a file's header
  // read before decoding does not count.
  uint64_t images_decoded() const { return images_decoded_; }

 protected:
  std::vector<BadFrame> skipped_;
  uint64_t images_decoded_ = 0;
};

// ---- Dataset roots (layout detected) ----

enum class DatasetLayout {
  kSceneFlow,  // .../frames_{cleanpass,finalpass}/.../{left,right}/NNNN.png (FT3D, Driving, Monkaa)
  kStereoDirs,  // any tree of <seq>/{left,right}/*.png without a frames_*pass component
  kKitti,       // [training|testing/]{image_2,image_3}/NNNNNN_KK.png
};
const char* DatasetLayoutName(DatasetLayout layout);

struct DatasetOptions : SourceOptions {
  // Scene Flow: which rendering pass to read when both frames_cleanpass and frames_finalpass
  // exist ("clean" or "final"). When only one exists, it is used whatever this says.
  std::string pass = "clean";
  // Only these sequences (names as DatasetInfo::sequences spells them), in the dataset's own
  // order; empty: all. A name the dataset does not have is an error naming it. A shard of a
  // sharded run (`sfrt run --shard`) reads its units this way.
  std::vector<std::string> sequences;
};

// What DetectDataset found under a root: the layout and the sequences in enumeration order.
struct DatasetInfo {
  DatasetLayout layout = DatasetLayout::kStereoDirs;
  std::string root;
  std::string pass;  // kSceneFlow: "cleanpass" or "finalpass"; otherwise empty
  std::vector<std::string> sequences;
  int64_t pairs = 0;  // frame pairs over all sequences (union of left and right names)
  // With DatasetOptions::sequences: the dataset's own counts, before the selection.
  size_t all_sequences = 0;
  int64_t all_pairs = 0;
};

// One line for logs: "Scene Flow dataset ROOT (frames_cleanpass, 4 sequences, 40 pairs)", with
// "2 of 4 sequences, 20 of 40 pairs" for a selection. The sources' Describe() says this.
std::string DescribeDataset(const DatasetInfo& info);

// Detection rules, in order:
//  1. root (or root/training, root/testing) holds image_2/ and image_3/  -> kKitti. Files are
//     grouped by their scene prefix (NNNNNN_KK.png -> scene NNNNNN, frame KK); each scene is a
//     sequence; the right image is image_3/ with the same name.
//  2. otherwise every directory under root (depth <= 8, symlinks followed, names sorted) that holds
//     both left/ and right/ subdirectories containing image files (.png .jpg .jpeg .ppm .pgm .bmp
//     .tif .tiff .webp) is a sequence; left and right frames pair by identical file name. If any
//     sequence path contains frames_cleanpass or frames_finalpass the layout is kSceneFlow and only
//     the chosen pass is read. root itself may be such a directory.
//  3. nothing found -> error naming the root.
Result<DatasetInfo> DetectDataset(const std::string& root, const DatasetOptions& options);
// The one-argument overloads use default options (overloads rather than default arguments: GCC 12
// warns maybe-uninitialized on a defaulted std::function member).
Result<DatasetInfo> DetectDataset(const std::string& root);
Result<std::unique_ptr<StereoSource>> OpenDatasetSource(const std::string& root,
                                                        const DatasetOptions& options);
Result<std::unique_ptr<StereoSource>> OpenDatasetSource(const std::string& root);

// ---- Two plain directories or glob patterns ----

// left_spec / right_spec: a directory (its image files, as in rule 2 above) or a glob(3) pattern
// (anything containing * ? or [). Each side is sorted by file name (byte order) and the i-th left
// pairs with the i-th right; if the counts differ, the unmatched frames are bad frames ("no right
// frame at position i"). One sequence named "".
Result<std::unique_ptr<StereoSource>> OpenPlainSource(const std::string& left_spec,
                                                      const std::string& right_spec,
                                                      const SourceOptions& options);
Result<std::unique_ptr<StereoSource>> OpenPlainSource(const std::string& left_spec,
                                                      const std::string& right_spec);
// The image files one side of OpenPlainSource would read, in its order (an error when the
// directory lists none or the glob matches none).
Result<std::vector<std::string>> ListFrameFiles(const std::string& spec);

// ---- Side-by-side stereo video ----

struct VideoOptions : SourceOptions {
  bool left_first = true;  // the left image is the left half of each frame
};

// Opens a video file whose frames hold both views side by side (width = 2 x eye width) through
// cv::VideoCapture (what it can decode depends on the OpenCV build; MJPG in AVI always works).
// An odd frame width is an error. A frame the decoder fails on ends the stream (VideoCapture
// cannot tell a corrupt frame from the end); if the container announced more frames, the early
// end is reported as a bad frame (error under kStop).
Result<std::unique_ptr<StereoSource>> OpenSbsVideoSource(const std::string& path,
                                                         const VideoOptions& options);
Result<std::unique_ptr<StereoSource>> OpenSbsVideoSource(const std::string& path);

// ---- Consecutive pairs ----

// Turns a source into windows (pair_t, pair_t+1) of consecutive pairs from the same sequence,
// by the rule of window_chain.h. Each pair appears in at most two windows (as `current` and then
// as `previous`); a sequence change restarts the chain, and a skipped frame (an index gap), a
// stamp gap or a stamp that goes backwards breaks it, so the first pair after it opens no window.
// The stamps are the frame numbers (file names' digits, video frame numbers; the place in the
// listing for a name without digits): a file missing from a numbered sequence is a gap, and a
// number that goes backwards (names that do not sort by number) restarts the chain.
// Reuses two FramePair slots (no per-window copies). Not thread-safe. The source must outlive it.
class PairWindow {
 public:
  explicit PairWindow(StereoSource* source) : source_(source) {}

  // kPair: previous() and current() hold a window; kEnd: no more windows. Errors from the source
  // are passed through.
  Result<Fetched> Next();
  const FramePair& previous() const { return slots_[1 - current_slot_]; }
  const FramePair& current() const { return slots_[current_slot_]; }
  // The chain's counts so far (windows formed and why pairs opened none).
  const ChainCounts& counts() const { return chain_.counts(); }

 private:
  StereoSource* source_;
  WindowChain chain_;
  FramePair slots_[2];
  int current_slot_ = 0;
  bool have_current_ = false;
};

}  // namespace sfrt::camera
