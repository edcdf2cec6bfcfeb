#pragma once
// Frame outputs: PNG through libpng, MP4 (H.264) through libavcodec/libavformat, on a writer thread.
#include <memory>
#include <string>

#include "render/renderer.hpp"

namespace lumen::render {

// Write an RGB image as PNG atomically (temporary name, then rename). Throws std::runtime_error naming the path.
void write_png(const std::string& path, const Image& image);
// Read a PNG (RGB or RGBA, 8-bit) for tests; throws on error.
Image read_png(const std::string& path);

// H.264 MP4 encoder; writes to a temporary name (path + ".tmp", MP4 muxer chosen explicitly) and renames on
// close(). Uses libx264 (preset veryfast, crf 20, one thread); when no H.264 encoder opens it falls back to
// MPEG-4 part 2, which codec() and probe_video() report. width and height must be even (std::invalid_argument).
class VideoEncoder {
 public:
  VideoEncoder(const std::string& path, int width, int height, int fps);
  ~VideoEncoder();  // abandons (removes the temporary) if close() was not called
  void add(const Image& image);
  void close();
  std::string codec() const;  // encoder in use: "libx264", or "mpeg4" on fallback

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Video facts read back by decoding (for tests and reports).
struct VideoInfo {
  int width = 0, height = 0, frames = 0;
  std::string codec;
};
VideoInfo probe_video(const std::string& path);

// Writer thread: takes frames, writes PNG frames (frames_dir/frame_000001.png ...) and/or the video,
// so the simulation thread never waits for compression. Reports its own throughput.
struct WriterStats {
  long frames = 0;
  double busy_seconds = 0.0;  // time spent encoding/writing
  double frames_per_second() const { return busy_seconds > 0 ? frames / busy_seconds : 0.0; }
};

class FrameWriter {
 public:
  // frames_dir empty: no PNG; video_path empty: no video. frames_dir must exist (std::invalid_argument).
  // Destroying without finish() drops queued frames and leaves no video.
  FrameWriter(const std::string& frames_dir, const std::string& video_path, int width, int height, int fps);
  ~FrameWriter();
  // Frame numbers start at 1, in push order. Blocks only while 8 frames are queued. After a writer error
  // frames are dropped (finish() reports the error). Throws std::invalid_argument on a size mismatch.
  void push(Image image);
  // Wait for the queue, finalise the video; rethrows the first writer error.
  WriterStats finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lumen::render
