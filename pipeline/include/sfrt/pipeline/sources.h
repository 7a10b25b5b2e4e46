// FrameSources for the pipeline: recorded files (camera/sources) and live V4L2 cameras
// (camera/v4l2), each turned into (t, t+1) windows.
//
// Replays: a dataset root (layout detected by camera::DetectDataset), two plain directories or
// globs, or a side-by-side video; windows come from camera::PairWindow, so they never span a
// sequence boundary or a skipped frame. Bad frames (missing, undecodable, size mismatch) are
// recorded by path; under BadFramePolicy::kStop the first one ends the run with an error naming
// it, under kSkip the run goes on.
//
// Cameras: camera::v4l2::StereoCapture (two devices paired by timestamp, or one side-by-side
// device); a window is the previous delivered pair and the newest one. Per-camera driver drops
// (sequence gaps), stale frames skipped for the newest, and frames left without a partner are
// counted. Disconnects, watchdog timeouts and I/O errors are counted and logged and the capture
// goes on (it reopens with back-off); a corrupt frame is a bad frame (kStop ends the run).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "sfrt/camera/stereo_source.h"
#include "sfrt/camera/v4l2/stereo.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

struct ReplaySpec {
  enum class Kind { kDataset, kPlain, kVideo };
  Kind kind = Kind::kDataset;
  std::string root;   // kDataset
  std::string left;   // kPlain: directory or glob
  std::string right;  // kPlain
  std::string video;  // kVideo: side-by-side video file
  std::string pass = "clean";
  // kDataset: only these sequences (camera::DatasetOptions::sequences; empty: all).
  std::vector<std::string> sequences;
  bool video_left_first = true;
  camera::BadFramePolicy on_bad_frame = camera::BadFramePolicy::kStop;
  // Passes over the files (>= 1). Each pass reopens the source and delivers the same windows
  // with the same output stems, so later passes overwrite earlier files: for soak runs.
  int64_t loops = 1;
};

// Checks a replay before a run, as far as that can be done without running it: the inputs exist
// and list frames, left and right list the same number of frames (kPlain), and a first (t, t+1)
// window can be formed. Bad frames do not fail the check (the run applies on_bad_frame to them).
// Returns the windows of one pass.
Result<int64_t> ProbeReplay(const ReplaySpec& spec);

// The source opens in FrameSource::Open().
std::unique_ptr<FrameSource> MakeReplaySource(const ReplaySpec& spec);
std::unique_ptr<FrameSource> MakeCameraSource(const v4l2::StereoConfig& config,
                                              camera::BadFramePolicy on_bad_frame);

}  // namespace sfrt::pipeline
