// Benchmarks of the render stage at 640x480 on the paper's organ (20 around, 26 along, 3 layers: 2160 nodes,
// 1040 outer + 1040 inner + 240 end triangles), and of the frame outputs: PNG encode, video encode, writer thread.
// Budget: the draw must be well under the 25 ms frame (40 fps); the writer must keep up with 40 fps on one core.
#include <benchmark/benchmark.h>
#include <png.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

#include "physics/mesh.hpp"
#include "render/renderer.hpp"
#include "render/writers.hpp"

namespace {

using lumen::render::CameraPreset;
using lumen::render::Framing;
using lumen::render::FrameView;
using lumen::render::Image;

constexpr int kWidth = 640, kHeight = 480, kFps = 40;

// The paper's organ, a dent that moves with the frame number (so normals change every frame), and two probes.
struct Organ {
  lumen::physics::TetMesh mesh;
  lumen::physics::HollowCylinderSpec spec;
  std::vector<double> positions;       // n x 3, metres
  std::vector<std::uint8_t> contact;   // per node
  Framing framing;

  Organ() {
    mesh = lumen::physics::make_hollow_cylinder(spec);
    positions.assign(mesh.rest.data(), mesh.rest.data() + mesh.rest.size());
    contact.assign(mesh.n_nodes(), 0);
    framing = lumen::render::frame_organ(mesh.rest.data(), mesh.n_nodes(), mesh.surface(lumen::physics::kInnerWall).data(),
                                         static_cast<int>(mesh.surface(lumen::physics::kInnerWall).rows()));
  }

  // Pinch the tube from above at an axial station that moves with the frame; flag the pinched nodes.
  FrameView frame(long k) {
    const double zc = spec.length * (0.3 + 0.4 * (0.5 + 0.5 * std::sin(0.1 * k)));
    for (int i = 0; i < mesh.n_nodes(); ++i) {
      const double x = mesh.rest(i, 0), y = mesh.rest(i, 1), z = mesh.rest(i, 2);
      const double w = std::exp(-std::pow((z - zc) / 0.012, 2)) * std::max(0.0, y / std::hypot(x, y));
      positions[3 * i + 1] = y - 0.009 * w;
      contact[i] = w > 0.7 ? 1 : 0;
    }
    FrameView v;
    v.positions = positions.data();
    v.n_points = mesh.n_nodes();
    using lumen::render::SurfaceStyle;
    v.surfaces.push_back({mesh.surface(lumen::physics::kOuterWall).data(), static_cast<int>(mesh.surface(lumen::physics::kOuterWall).rows()), SurfaceStyle::outer_wall()});
    v.surfaces.push_back({mesh.surface(lumen::physics::kEndCaps).data(), static_cast<int>(mesh.surface(lumen::physics::kEndCaps).rows()), SurfaceStyle::wall_ends()});
    v.surfaces.push_back({mesh.surface(lumen::physics::kInnerWall).data(), static_cast<int>(mesh.surface(lumen::physics::kInnerWall).rows()), SurfaceStyle::inner_wall()});
    v.contact = contact.data();
    v.force_scale = 0.02;
    v.probes.push_back({Eigen::Vector3d(0, spec.outer_radius - 0.009, zc), Eigen::Vector3d(0, -1.0, 0)});
    v.probes.push_back({Eigen::Vector3d(0, -spec.outer_radius, spec.length * 0.2), Eigen::Vector3d(0, 0.5, 0)});
    return v;
  }
};

// A few distinct rendered frames (diagonal view), the realistic input of the encoders.
const std::vector<Image>& rendered_frames() {
  static const std::vector<Image> frames = [] {
    Organ organ;
    lumen::render::Renderer renderer(kWidth, kHeight, CameraPreset::Diagonal, organ.framing);
    std::vector<Image> out(16);
    for (int k = 0; k < 16; ++k) renderer.draw(organ.frame(3 * k), out[k]);
    return out;
  }();
  return frames;
}

std::string scratch_dir() {
  const auto dir = std::filesystem::temp_directory_path() / ("lumen_bench_render_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir.string();
}

// Renderer::draw: normals, colours, arrows, three passes with the cut-away, glFinish and read-back.
void BM_RenderDraw(benchmark::State& state) {
  Organ organ;
  lumen::render::Renderer renderer(kWidth, kHeight, static_cast<CameraPreset>(state.range(0)), organ.framing);
  Image image;
  long k = 0;
  for (auto _ : state) {
    renderer.draw(organ.frame(k++), image);
    benchmark::DoNotOptimize(image.rgb.data());
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(state.range(0) == 0 ? "side" : state.range(0) == 1 ? "diagonal" : "endoscope");
}
// Real time: llvmpipe rasterises on its own worker threads.
BENCHMARK(BM_RenderDraw)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// write_png: libpng at level 1 with the Sub filter, into a temporary file renamed onto the final name.
void BM_PngWrite(benchmark::State& state) {
  const auto& frames = rendered_frames();
  const std::string path = scratch_dir() + "/frame.png";
  size_t k = 0;
  for (auto _ : state) lumen::render::write_png(path, frames[k++ % frames.size()]);
  state.counters["bytes"] = static_cast<double>(std::filesystem::file_size(path));
  std::filesystem::remove_all(std::filesystem::path(path).parent_path());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PngWrite)->Unit(benchmark::kMillisecond);

// Reference points for the compression choice: libpng's own defaults (zlib level 6, adaptive filters) and its
// "fast" flag (level 3, no filter), encoding to memory through the simplified API.
void BM_PngLibpngReference(benchmark::State& state) {
  const auto& frames = rendered_frames();
  size_t k = 0;
  size_t bytes = 0;
  std::vector<unsigned char> buffer(static_cast<size_t>(kWidth) * kHeight * 4 + 4096);
  for (auto _ : state) {
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    img.width = kWidth;
    img.height = kHeight;
    img.format = PNG_FORMAT_RGB;
    img.flags = state.range(0) ? PNG_IMAGE_FLAG_FAST : 0;
    png_alloc_size_t size = buffer.size();
    if (!png_image_write_to_memory(&img, buffer.data(), &size, 0, frames[k++ % frames.size()].rgb.data(), 0, nullptr)) {
      state.SkipWithError(img.message);
      break;
    }
    bytes = size;
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.SetLabel(state.range(0) ? "libpng fast flag" : "libpng default");
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PngLibpngReference)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// VideoEncoder::add: RGB -> YUV420P and libx264 (veryfast, crf 20, one thread), per frame.
void BM_VideoEncode(benchmark::State& state) {
  const auto& frames = rendered_frames();
  const std::string dir = scratch_dir();
  {
    lumen::render::VideoEncoder encoder(dir + "/video.mp4", kWidth, kHeight, kFps);
    size_t k = 0;
    for (auto _ : state) encoder.add(frames[k++ % frames.size()]);
    encoder.close();
    state.SetLabel(encoder.codec());
  }
  std::filesystem::remove_all(dir);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_VideoEncode)->Unit(benchmark::kMillisecond);

// FrameWriter: PNG frames and the video on the writer thread; the counter is the thread's own throughput.
void BM_FrameWriter(benchmark::State& state) {
  const auto& frames = rendered_frames();
  const int n = 80;  // two seconds of session per iteration
  double fps = 0;
  for (auto _ : state) {
    const std::string dir = scratch_dir();
    lumen::render::FrameWriter writer(dir, dir + "/video.mp4", kWidth, kHeight, kFps);
    for (int k = 0; k < n; ++k) writer.push(frames[k % frames.size()]);
    fps = writer.finish().frames_per_second();
    std::filesystem::remove_all(dir);
  }
  state.counters["writer_fps"] = fps;
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_FrameWriter)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

}  // namespace
