// sfrt synth's scenes in the KITTI Scene Flow 2015 training layout (eval/kitti.h), so the KITTI
// path of `sfrt eval` has fixtures with exact ground truth (`sfrt synth --layout kitti`).
//
// Scene k is frames f -> f+1 of sequence s (k counts them in order): image_2/image_3 at _10
// (frame f) and _11 (frame f+1); disp_occ_0 the disparity at f; disp_occ_1 the disparity the
// same points have at f+1 (d0 + disparity change, on the grid of f, as KITTI defines it);
// flow_occ the optical flow; obj_map the object index (0: the room, the background); the
// calibration from the rig. Disparity at t+1 and flow have no value where the point leaves the
// image at f+1 (as in KITTI, whose ground truth ends at the image border); everything else has
// one (KITTI's laser ground truth is sparse; this is dense). Encoded as the devkit encodes them,
// so the values carry its quantisation (1/256 px, 1/64 px).
#pragma once

#include <functional>
#include <string>

#include "sfrt/status.h"
#include "synth/dataset.h"

namespace sfrt::eval {

// Writes OUT/training/... under a temporary sibling and renames it into place when complete;
// `out_dir` must be new or empty. `progress(done, total)` after each scene.
Status WriteKittiLayout(const synth::DatasetOptions& options, const std::string& out_dir,
                        const std::function<void(int done, int total)>& progress = {});

}  // namespace sfrt::eval
