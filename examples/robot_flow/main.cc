// robot_flow: the smallest robot program on sfrt. Two cameras in, one flow frame per stereo pair
// out, handed to the program's own code in-process (here: a line with the frame's latency and
// its mean forward motion). Built against the installed package (CMakeLists.txt beside it).
//
// usage: robot_flow MODEL.sfrt LEFT_DEVICE RIGHT_DEVICE [FRAMES] [HxW]
//   FRAMES  windows to receive, then stop (default 100; 0 = until Ctrl-C)
//   HxW     network input size (default 96x128)
// Prints one line per frame: window, camera sequence numbers, end-to-end latency so far (ms),
// mean dZ (the model's units); then a summary line. Exit status 0 when every frame arrived.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "sfrt/camera/v4l2/stereo.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/sources.h"

namespace {

std::atomic<bool> g_stop{false};
std::atomic<int> g_signal{0};

void OnSignal(int sig) {
  g_signal = sig;
  g_stop = true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: robot_flow MODEL.sfrt LEFT_DEVICE RIGHT_DEVICE [FRAMES] [HxW]\n");
    return 2;
  }
  const long frames = argc > 4 ? std::strtol(argv[4], nullptr, 10) : 100;
  int height = 96, width = 128;
  if (argc > 5 && std::sscanf(argv[5], "%dx%d", &height, &width) != 2) {
    std::fprintf(stderr, "robot_flow: size '%s' is not HxW\n", argv[5]);
    return 2;
  }

  // 1. The model, loaded and verified once.
  auto model = sfrt::Model::LoadFile(argv[1]);
  if (!model.ok()) {
    std::fprintf(stderr, "robot_flow: %s\n", model.message().c_str());
    return 1;
  }
  // 2. The cameras: two V4L2 devices, paired by timestamp.
  sfrt::v4l2::StereoConfig cameras;
  cameras.left.device = argv[2];
  cameras.right.device = argv[3];
  auto source = sfrt::pipeline::MakeCameraSource(cameras, sfrt::camera::BadFramePolicy::kSkip);
  // 3. The flow, in-process: valid only during the call (copy what must outlive it).
  long received = 0;
  sfrt::pipeline::CallbackSink sink([&](const sfrt::pipeline::FlowFrame& f) {
    double dz = 0;
    for (size_t i = 2; i < f.flow.size(); i += static_cast<size_t>(f.channels)) dz += f.flow[i];
    dz /= static_cast<double>(f.flow.size() / static_cast<size_t>(f.channels));
    std::printf("window %lld frames %lld-%lld latency %.2f ms dZ %.4f\n",
                static_cast<long long>(f.meta->window), static_cast<long long>(f.meta->frame0),
                static_cast<long long>(f.meta->frame1), f.latency_ms, dz);
    ++received;
    return sfrt::Status::Ok();
  });
  // 4. The pipeline: no files, one inference thread, stop on Ctrl-C or after FRAMES windows.
  sfrt::pipeline::PipelineOptions options;
  options.out_dir = ".";
  options.write_flow = false;
  options.write_png = false;
  options.write_summary = false;
  options.progress = sfrt::pipeline::ProgressMode::kOff;
  options.height = height;
  options.width = width;
  options.max_frames = frames;
  options.sinks.push_back(&sink);
  options.stop = &g_stop;
  options.stop_signal = &g_signal;
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const sfrt::pipeline::PipelineResult r =
      sfrt::pipeline::RunPipeline(*model, source.get(), options);
  if (!r.status.ok()) {
    std::fprintf(stderr, "robot_flow: %s\n", r.status.message().c_str());
    return 1;
  }
  std::printf("received %ld frames (%s), %.1f fps, end to end p50 %.2f ms p99 %.2f ms\n", received,
              r.stopped_by.c_str(), r.fps, r.end_to_end.p50, r.end_to_end.p99);
  return received == r.frames ? 0 : 1;
}
