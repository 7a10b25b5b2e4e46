// Ground-truth scene flow from a Scene Flow dataset tree (disparity, disparity change and
// optical flow into the future), per docs: SceneEDNet's ground-truth construction.
//
// Formula (ConventionKind::kFormula), for left pixel (col, row) at t with disparity d0, flow
// (u, v) and d1 = d0 + disparity_change (the same point's disparity at t+1):
//   Z0 = f B / d0, X0 = (col - cx) Z0 / f, Y0 = (row - cy) Z0 / f
//   Z1 = f B / d1, X1 = (col + u - cx) Z1 / f, Y1 = (row + v - cy) Z1 / f
//   scene flow = (X1 - X0, Y1 - Y0, Z1 - Z0)
// Pixels with d0 <= 0 or d1 <= 0 (or a non-finite input) are invalid: NaN in all three channels.
//
// ConventionKind::kAuthorsPublished reproduces the ground truth published with the authors'
// code (readfiles.py sceneflowconstruct): d1 is the disparity map of frame t+1 read at the SAME
// pixel (not where the point moved), and the row index is paired with cx and the flow u:
//   X0 = (row - cx) Z0 / f,  Y0 = (col - cy) Z0 / f
//   X1 = (row + u - cx) Z1 / f,  Y1 = (col + v - cy) Z1 / f
// (The authors' loader also pairs frame t with the flow file of frame t+1; that file pairing is
// not reproduced: the flow of frame t is used.)
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::synth {

enum class ConventionKind { kFormula, kAuthorsPublished };

struct Intrinsics {
  double focal = 1050;
  double baseline = 1;
  double cx = 479.5;
  double cy = 269.5;
};

// Intrinsics of the Scene Flow subsets: "flyingthings3d", "monkaa", "driving35mm" (f = 1050) and
// "driving15mm" (f = 450); cx = 479.5, cy = 269.5, B = 1. False for an unknown name.
bool SubsetIntrinsics(const std::string& subset, Intrinsics* out);

// Reads focal, baseline, cx and cy from the camera.json that `sfrt synth` writes.
Result<Intrinsics> ReadCameraJson(const std::string& path);

// Scene flow for one frame. d0: H*W disparity at t. second: H*W, the disparity change
// (kFormula: d1 = d0 + second, summed in double) or the disparity map of frame t+1
// (kAuthorsPublished: d1 = second). flow: H*W*flow_channels (u, v first). out: H*W*3.
// Returns the number of invalid pixels (set to NaN).
size_t ComputeSceneFlow(const float* d0, const float* second, const float* flow, int flow_channels,
                        int height, int width, const Intrinsics& k, ConventionKind convention,
                        float* out);

struct AnnotateSummary {
  int frames_written = 0;
  int frames_found = 0;       // disparity files <rel>/left/NNNN.pfm found
  int frames_skipped = 0;     // a needed input file is missing
  std::string first_skipped;  // why the first skipped frame was skipped
  size_t pixels = 0;
  size_t invalid_pixels = 0;
};

struct AnnotateFrameInfo {
  int index = 0;       // among the disparity files found (0-based)
  int total = 0;       // disparity files found
  std::string output;  // the file written
  size_t pixels = 0;
  size_t invalid = 0;
};

// Walks DATASET_ROOT/disparity for every "<rel>/left/NNNN.pfm" (sorted) and writes
// OUT/scene_flow/<rel>/into_future/left/NNNN.pfm (3-channel PFM, atomically). Inputs per frame:
//   kFormula:          disparity_change/<rel>/into_future/left/NNNN.pfm and
//                      optical_flow/<rel>/into_future/left/OpticalFlowIntoFuture_NNNN_L.pfm
//   kAuthorsPublished: disparity/<rel>/left/<NNNN+1>.pfm and the same optical flow file.
// A frame whose inputs are missing is skipped and counted; unreadable or mismatched files are
// errors naming the file.
Result<AnnotateSummary> AnnotateTree(
    const std::string& root, const std::string& out, const Intrinsics& k, ConventionKind convention,
    const std::function<void(const AnnotateFrameInfo&)>& on_frame = {});

}  // namespace sfrt::synth
