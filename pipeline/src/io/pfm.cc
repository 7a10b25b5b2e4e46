#include "sfrt/pipeline/io/pfm.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>

#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/byte_order.h"

namespace sfrt::io {
namespace {

// Largest accepted side: far beyond any camera, small enough that h * w * 3 * 4 cannot overflow.
constexpr long long kMaxSide = 1 << 20;

bool IsSpace(char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; }

// Splits the PFM header into its three fields, tolerating extra spaces.
class HeaderReader {
 public:
  explicit HeaderReader(std::string_view bytes) : bytes_(bytes) {}

  void SkipSpace() {
    while (pos_ < bytes_.size() && IsSpace(bytes_[pos_])) ++pos_;
  }
  // The next run of non-space characters (empty at the end of the input). Stops early at a
  // 64-character limit so that binary garbage is not scanned far.
  std::string_view Token() {
    SkipSpace();
    size_t start = pos_;
    while (pos_ < bytes_.size() && !IsSpace(bytes_[pos_]) && pos_ - start < 64) ++pos_;
    return bytes_.substr(start, pos_ - start);
  }
  // After the last header field: spaces/tabs/'\r' up to and including one '\n'.
  bool EndOfHeaderLine() {
    while (pos_ < bytes_.size() &&
           (bytes_[pos_] == ' ' || bytes_[pos_] == '\t' || bytes_[pos_] == '\r')) {
      ++pos_;
    }
    if (pos_ >= bytes_.size() || bytes_[pos_] != '\n') return false;
    ++pos_;
    return true;
  }
  size_t pos() const { return pos_; }

 private:
  std::string_view bytes_;
  size_t pos_ = 0;
};

std::string Printable(std::string_view token) {
  std::string out;
  for (char c : token) {
    if (std::isprint(static_cast<unsigned char>(c))) {
      out.push_back(c);
    } else {
      out += "?";
    }
  }
  return out;
}

bool ParseSide(std::string_view token, long long* value) {
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  return ec == std::errc() && ptr == end;
}

}  // namespace

Result<PfmImage> ParsePfm(std::string_view bytes, const std::string& label) {
  auto bad = [&](const std::string& what) {
    return Status::Error(label + ": bad PFM header: " + what);
  };
  HeaderReader reader(bytes);
  std::string_view magic = reader.Token();
  PfmImage image;
  if (magic == "PF") {
    image.channels = 3;
  } else if (magic == "Pf") {
    image.channels = 1;
  } else {
    return bad("identifier is '" + Printable(magic) + "', expected 'PF' (colour) or 'Pf' (grey)");
  }
  std::string_view width_token = reader.Token();
  std::string_view height_token = reader.Token();
  long long width = 0;
  long long height = 0;
  if (!ParseSide(width_token, &width) || width <= 0 || width > kMaxSide) {
    return bad("width is '" + Printable(width_token) + "', expected a positive integer");
  }
  if (!ParseSide(height_token, &height) || height <= 0 || height > kMaxSide) {
    return bad("height is '" + Printable(height_token) + "', expected a positive integer");
  }
  std::string_view scale_token = reader.Token();
  double scale = 0;
  {
    const char* end = scale_token.data() + scale_token.size();
    auto [ptr, ec] = std::from_chars(scale_token.data(), end, scale);
    if (ec != std::errc() || ptr != end || !std::isfinite(scale) || scale == 0) {
      return bad("scale is '" + Printable(scale_token) +
                 "', expected a non-zero number (negative: little-endian, positive: big-endian)");
    }
  }
  if (!reader.EndOfHeaderLine()) return bad("the scale line does not end with a newline");
  const bool little_endian = scale < 0;

  image.width = static_cast<int>(width);
  image.height = static_cast<int>(height);
  const size_t row_floats = static_cast<size_t>(width) * static_cast<size_t>(image.channels);
  const size_t count = row_floats * static_cast<size_t>(height);
  const size_t available = bytes.size() - reader.pos();
  if (available != count * sizeof(float)) {
    return Status::Error(label + ": PFM header says " + std::to_string(width) + "x" +
                         std::to_string(height) + " with " + std::to_string(image.channels) +
                         " channel(s), which needs " + std::to_string(count * sizeof(float)) +
                         " bytes of pixel data, but " + std::to_string(available) +
                         " follow the header" +
                         (available < count * sizeof(float) ? " (file truncated?)" : ""));
  }
  image.data.resize(count);
  const char* pixels = bytes.data() + reader.pos();
  for (long long row = 0; row < height; ++row) {
    // File row 0 is the bottom of the image.
    const char* src = pixels + static_cast<size_t>(height - 1 - row) * row_floats * sizeof(float);
    LoadFloats(src, row_floats, little_endian, image.data.data() + row * row_floats);
  }
  return image;
}

Result<PfmImage> ReadPfm(const std::string& path) {
  Result<std::string> bytes = ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  return ParsePfm(*bytes, path);
}

Result<std::vector<uint8_t>> SerializePfm(std::span<const float> data, int height, int width,
                                          int channels) {
  if (channels != 1 && channels != 3) {
    return Status::Error("cannot write PFM: it holds 1 or 3 channels, not " +
                         std::to_string(channels));
  }
  if (height <= 0 || width <= 0 || height > kMaxSide || width > kMaxSide) {
    return Status::Error("cannot write PFM: invalid size " + std::to_string(height) + "x" +
                         std::to_string(width));
  }
  const size_t row_floats = static_cast<size_t>(width) * static_cast<size_t>(channels);
  const size_t count = row_floats * static_cast<size_t>(height);
  if (data.size() != count) {
    return Status::Error("cannot write PFM: " + std::to_string(height) + "x" +
                         std::to_string(width) + "x" + std::to_string(channels) + " needs " +
                         std::to_string(count) + " floats but " + std::to_string(data.size()) +
                         " were given");
  }
  const std::string header = std::string(channels == 3 ? "PF" : "Pf") + "\n" +
                             std::to_string(width) + " " + std::to_string(height) + "\n-1.0\n";
  std::vector<uint8_t> out(header.size() + count * sizeof(float));
  std::memcpy(out.data(), header.data(), header.size());
  uint8_t* pixels = out.data() + header.size();
  for (int row = 0; row < height; ++row) {
    const float* src = data.data() + static_cast<size_t>(height - 1 - row) * row_floats;
    StoreFloatsLittleEndian(src, row_floats, pixels + static_cast<size_t>(row) * row_floats * 4);
  }
  return out;
}

Status WritePfm(const std::string& path, std::span<const float> data, int height, int width,
                int channels) {
  Result<std::vector<uint8_t>> bytes = SerializePfm(data, height, width, channels);
  if (!bytes.ok()) return Status::Error(path + ": " + bytes.message());
  return WriteFileAtomically(path, *bytes);
}

}  // namespace sfrt::io
