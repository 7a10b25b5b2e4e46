// Runs one frame through an installed sfrt runtime: consumer MODEL INPUT.f32 HEIGHT WIDTH OUT.f32
// INPUT.f32 holds HEIGHT x WIDTH x 12 float32 (NHWC, the model's channel order); OUT.f32 gets the
// flow, HEIGHT x WIDTH x 3 float32.
#include <sfrt/model.h>
#include <sfrt/session.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: %s MODEL INPUT.f32 HEIGHT WIDTH OUT.f32\n", argv[0]);
    return 2;
  }
  const int height = std::stoi(argv[3]);
  const int width = std::stoi(argv[4]);

  auto model = sfrt::Model::LoadFile(argv[1]);
  if (!model.ok()) {
    std::fprintf(stderr, "%s\n", model.message().c_str());
    return 1;
  }
  sfrt::SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  auto session = sfrt::Session::Create(*model, options);
  if (!session.ok()) {
    std::fprintf(stderr, "%s\n", session.message().c_str());
    return 1;
  }
  auto shape = (*session)->OutputShape(height, width);
  if (!shape.ok()) {
    std::fprintf(stderr, "%s\n", shape.message().c_str());
    return 1;
  }

  std::vector<float> input(static_cast<size_t>(height) * width * 12);
  std::ifstream in(argv[2], std::ios::binary);
  in.read(reinterpret_cast<char*>(input.data()), static_cast<std::streamsize>(input.size() * 4));
  if (!in || in.peek() != EOF) {
    std::fprintf(stderr, "%s: expected exactly %zu float32 values\n", argv[2], input.size());
    return 1;
  }
  std::vector<float> output(shape->elements());
  if (sfrt::Status s = (*session)->Run(input, height, width, output); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 1;
  }
  std::ofstream out(argv[5], std::ios::binary);
  out.write(reinterpret_cast<const char*>(output.data()),
            static_cast<std::streamsize>(output.size() * 4));
  if (!out.flush()) {
    std::fprintf(stderr, "%s: write failed\n", argv[5]);
    return 1;
  }
  std::printf("%s: %dx%d on %s, output %dx%dx%d\n", argv[1], height, width,
              sfrt::IsaName((*session)->isa()), shape->height, shape->width, shape->channels);
  return 0;
}
