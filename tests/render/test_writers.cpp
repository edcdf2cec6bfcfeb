// Frame output tests: PNG round trip and atomic writes, MP4 decoded back, the writer thread's files and errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include "render/writers.hpp"

namespace lumen::render {
namespace {

namespace fs = std::filesystem;

// A fresh empty folder per test, removed afterwards.
class TempDir {
 public:
  explicit TempDir(const std::string& tag)
      : path_(fs::temp_directory_path() / ("lumen_render_" + tag + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  const fs::path& path() const { return path_; }
  std::set<std::string> names() const {
    std::set<std::string> out;
    for (const auto& e : fs::directory_iterator(path_)) out.insert(e.path().filename().string());
    return out;
  }

 private:
  fs::path path_;
};

// Random-noise image: any pixel mix-up or lossy step shows.
Image noise_image(int w, int h, unsigned seed) {
  Image im;
  im.width = w;
  im.height = h;
  im.rgb.resize(static_cast<size_t>(w) * h * 3);
  std::mt19937 rng(seed);
  for (auto& v : im.rgb) v = static_cast<std::uint8_t>(rng() & 0xff);
  return im;
}

// Smooth moving gradient, a typical video frame.
Image gradient_image(int w, int h, int frame) {
  Image im;
  im.width = w;
  im.height = h;
  im.rgb.resize(static_cast<size_t>(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = &im.rgb[(static_cast<size_t>(y) * w + x) * 3];
      p[0] = static_cast<std::uint8_t>((x + 4 * frame) & 0xff);
      p[1] = static_cast<std::uint8_t>(y & 0xff);
      p[2] = static_cast<std::uint8_t>((x + y + 8 * frame) & 0xff);
    }
  return im;
}

TEST(Png, RoundTripIsExact) {
  TempDir dir("png_round_trip");
  const Image im = noise_image(37, 23, 1);
  write_png(dir / "a.png", im);
  const Image back = read_png(dir / "a.png");
  EXPECT_EQ(back.width, im.width);
  EXPECT_EQ(back.height, im.height);
  EXPECT_EQ(back.rgb, im.rgb);
  EXPECT_EQ(dir.names(), std::set<std::string>{"a.png"});
  // Overwriting an existing file replaces it.
  const Image im2 = gradient_image(64, 48, 3);
  write_png(dir / "a.png", im2);
  EXPECT_EQ(read_png(dir / "a.png").rgb, im2.rgb);
}

TEST(Png, UnwritableDirectoryThrowsNamingThePathAndLeavesNothing) {
  TempDir dir("png_unwritable");
  const std::string path = dir / "missing/frame.png";
  try {
    write_png(path, noise_image(8, 8, 2));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_TRUE(dir.names().empty());
}

TEST(Png, FailedRenameRemovesTheTemporary) {
  // The final name is an existing folder: encoding succeeds, the rename fails, the temporary goes.
  TempDir dir("png_rename");
  fs::create_directory(dir / "frame.png");
  try {
    write_png(dir / "frame.png", noise_image(8, 8, 3));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(dir / "frame.png"), std::string::npos) << e.what();
  }
  EXPECT_EQ(dir.names(), std::set<std::string>{"frame.png"});
  EXPECT_TRUE(fs::is_directory(dir / "frame.png"));
}

TEST(Png, RejectsMalformedImagesAndMissingFiles) {
  TempDir dir("png_bad");
  Image im = noise_image(8, 8, 4);
  im.rgb.pop_back();
  EXPECT_THROW(write_png(dir / "x.png", im), std::invalid_argument);
  EXPECT_THROW(write_png(dir / "x.png", Image{}), std::invalid_argument);
  EXPECT_THROW(read_png(dir / "none.png"), std::runtime_error);
  EXPECT_TRUE(dir.names().empty());
}

TEST(Video, DecodesBackToTheFrameCountAndSize) {
  TempDir dir("video");
  const std::string path = dir / "video.mp4";
  std::string codec;
  {
    VideoEncoder enc(path, 320, 240, 40);
    codec = enc.codec();
    for (int k = 0; k < 12; ++k) enc.add(gradient_image(320, 240, k));
    EXPECT_TRUE(fs::exists(path + ".tmp"));
    EXPECT_FALSE(fs::exists(path));
    enc.close();
  }
  EXPECT_EQ(dir.names(), std::set<std::string>{"video.mp4"});
  const VideoInfo info = probe_video(path);
  EXPECT_EQ(info.frames, 12);
  EXPECT_EQ(info.width, 320);
  EXPECT_EQ(info.height, 240);
  // H.264 through libx264 when it is available (Debian's FFmpeg has it), MPEG-4 part 2 otherwise.
  EXPECT_EQ(info.codec, codec == "mpeg4" ? "mpeg4" : "h264") << "encoder " << codec;
}

TEST(Video, ValidatesAndAbandonsCleanly) {
  TempDir dir("video_bad");
  EXPECT_THROW(VideoEncoder(dir / "v.mp4", 321, 240, 40), std::invalid_argument);
  EXPECT_THROW(VideoEncoder(dir / "v.mp4", 320, 241, 40), std::invalid_argument);
  EXPECT_THROW(VideoEncoder(dir / "v.mp4", 320, 240, 0), std::invalid_argument);
  try {
    VideoEncoder enc(dir / "missing/v.mp4", 320, 240, 40);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(dir / "missing/v.mp4"), std::string::npos) << e.what();
  }
  {
    VideoEncoder enc(dir / "v.mp4", 64, 48, 40);
    enc.add(gradient_image(64, 48, 0));
    EXPECT_THROW(enc.add(gradient_image(32, 48, 0)), std::invalid_argument);
    // Destroyed without close(): abandoned.
  }
  EXPECT_TRUE(dir.names().empty());
  EXPECT_THROW(probe_video(dir / "none.mp4"), std::runtime_error);
}

TEST(FrameWriter, WritesNumberedPngsAndTheVideo) {
  TempDir dir("writer");
  fs::create_directory(dir / "frames");
  const int n = 20;  // more than the queue holds, so push() has to wait for the writer
  std::vector<Image> pushed;
  WriterStats stats;
  {
    FrameWriter writer(dir / "frames", dir / "video.mp4", 96, 64, 40);
    for (int k = 0; k < n; ++k) {
      pushed.push_back(noise_image(96, 64, 100 + k));
      writer.push(pushed.back());
    }
    stats = writer.finish();
  }
  EXPECT_EQ(stats.frames, n);
  EXPECT_GT(stats.busy_seconds, 0.0);
  std::set<std::string> expected;
  for (int k = 1; k <= n; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%06d.png", k);
    expected.insert(name);
    EXPECT_EQ(read_png(dir / ("frames/" + std::string(name))).rgb, pushed[k - 1].rgb) << name;
  }
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir / "frames")) names.insert(e.path().filename().string());
  EXPECT_EQ(names, expected);  // and so no .tmp remains
  EXPECT_EQ(dir.names(), (std::set<std::string>{"frames", "video.mp4"}));
  EXPECT_EQ(probe_video(dir / "video.mp4").frames, n);
}

TEST(FrameWriter, RethrowsTheFirstErrorAndLeavesNoTemporary) {
  // frame_000003.png is taken by a folder: frames 1 and 2 are written, then finish() reports frame 3.
  TempDir dir("writer_error");
  fs::create_directory(dir / "frame_000003.png");
  FrameWriter writer(dir.path().string(), "", 16, 16, 40);
  for (int k = 0; k < 12; ++k) writer.push(noise_image(16, 16, k));
  try {
    writer.finish();
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("frame_000003.png"), std::string::npos) << e.what();
  }
  EXPECT_EQ(dir.names(), (std::set<std::string>{"frame_000001.png", "frame_000002.png", "frame_000003.png"}));
}

TEST(FrameWriter, ValidatesAndAbandonsWithoutFinish) {
  TempDir dir("writer_bad");
  EXPECT_THROW(FrameWriter(dir / "missing", "", 16, 16, 40), std::invalid_argument);
  EXPECT_THROW(FrameWriter("", dir / "v.mp4", 15, 16, 40), std::invalid_argument);
  {
    FrameWriter writer("", dir / "v.mp4", 16, 16, 40);
    EXPECT_THROW(writer.push(noise_image(8, 16, 0)), std::invalid_argument);
    writer.push(noise_image(16, 16, 0));
  }
  EXPECT_TRUE(dir.names().empty());
}

}  // namespace
}  // namespace lumen::render
