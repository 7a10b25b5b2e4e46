// Writes synthetic sequences in the layout of the Scene Flow datasets (FlyingThings3D, Driving,
// Monkaa), so the same loaders read real and synthetic data:
//
//   DIR/camera.json                                          rig, generator settings, "complete"
//   DIR/camera_data/<seq>/camera_data.txt                    poses in the datasets' format
//   DIR/frames_cleanpass/<seq>/{left,right}/NNNN.png         8-bit BGR images
//   DIR/disparity/<seq>/left/NNNN.pfm                        1 channel, positive, px
//   DIR/disparity_change/<seq>/into_future/left/NNNN.pfm     1 channel, px
//   DIR/optical_flow/<seq>/into_future/left/OpticalFlowIntoFuture_NNNN_L.pfm   u, v, 0 (px)
//   DIR/scene_flow/<seq>/into_future/left/NNNN.pfm           dX, dY, dZ (scene units)
//
// <seq> and NNNN are 4-digit numbers from 0000. The ground truth of every frame, including the
// last, is "into the future" (see render.h for its definition). camera_data.txt holds, as the
// datasets do, camera-to-world 4x4 matrices in Blender axes (x right, y up, looking along -z);
// the rig does not move (ego-motion is the room's motion), so every frame has the same poses:
// L = diag(1, -1, -1, 1), R = L with translation (baseline, 0, 0).
//
// The images' pixel values depend only on the options (and the texture files); the PNG bytes
// also depend on the zlib build.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "sfrt/status.h"
#include "synth/render.h"
#include "synth/scene.h"

namespace sfrt::synth {

struct DatasetOptions {
  SceneOptions scene;  // camera, frames per sequence, objects per scene
  int sequences = 1;
  uint64_t seed = 0;
  std::string texture_dir;  // empty: procedural textures
  double noise_sigma = 0;   // 8-bit grey levels
  double blur_sigma = 0;    // pixels
  int threads = 1;
  // Set (by a signal handler) to stop between frames: WriteDataset then removes the partial
  // tree, leaves the destination as it was and returns an error saying it was stopped.
  const std::atomic<bool>* stop = nullptr;
};

struct DatasetProgress {
  int sequence = 0;
  int frame = 0;
  int frames_done = 0;  // over all sequences, including this one
  int frames_total = 0;
};

// The relative file names of one frame's outputs.
std::string SequenceName(int sequence);
std::string FrameName(int frame);

// What is at a data set's destination. WriteDataset writes to kAbsent and kEmptyDirectory, and
// with `replace` to kSynthDataset (a folder whose camera.json says "generator": "sfrt synth",
// complete or not); it refuses the others, so replacing never deletes a folder sfrt did not make.
// A symbolic link is followed.
enum class Destination { kAbsent, kEmptyDirectory, kSynthDataset, kOtherDirectory, kNotADirectory };
Destination ClassifyDestination(const std::string& out_dir);

// Generates the data set at `out_dir` (see ClassifyDestination). Everything is written under
// a temporary sibling, "<out_dir>.partial-<pid>", and flushed file by file; camera.json, with
// "complete": true, is written last; only then is the tree renamed to `out_dir` (an existing
// data set there is replaced only at this point). On any failure the temporary tree is removed
// and `out_dir` is left as it was: a full disk, or a stop (DatasetOptions::stop: SIGINT,
// SIGTERM), leaves no partial data set behind.
// `progress` (optional) is called after each frame.
Status WriteDataset(const DatasetOptions& options, const std::string& out_dir, bool replace = false,
                    const std::function<void(const DatasetProgress&)>& progress = {});

// sfrt eval's guard: a folder whose camera.json says sfrt synth wrote it must also say
// "complete": true (written last; missing after an interrupted or failed generation, and in
// data sets from sfrt versions before the marker). Data sets sfrt synth did not write (a
// camera.json without that generator, e.g. written by hand for Scene Flow data) are not checked.
Status CheckDatasetComplete(const std::string& dir);

// Renders frames of sequence `sequence` without writing them (for tests and tools).
Result<Scene> MakeDatasetScene(const DatasetOptions& options, int sequence);
RenderOptions MakeRenderOptions(const DatasetOptions& options, int sequence);

}  // namespace sfrt::synth
