// Output: frame buffers and their capture, particle snapshots and frames (by ID), frames handed to the writer
// thread, and the totals tests read (mass, energy, grid mass, device bytes). Part of MgspBenchmark.
#pragma once

#include <cub/device/device_scan.cuh>

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
void MgspBenchmark<T, TG>::allocate_frames() {
  if (!options_.frames) return;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;  // frame_attrs: resolved for the plan
    const FrameNeeds needs = frame_needs(b.frame_attrs);
    FrameCapture<T> cap;
    if (frame_float_columns(b.frame_attrs) > kMaxFrameColumns)
      throw std::invalid_argument("bodies[" + std::to_string(b.index) + "].output_attribs: more than " +
                                  std::to_string(kMaxFrameColumns) + " attributes besides ID");
    for (const FrameAttributeSpec& a : b.frame_attrs)
      if (a.column.quantity != FrameQuantity::Id) cap.column[cap.column_count++] = a.column;
    cap.sigma = needs.sigma;
    // One GPU: one entry per ID. A decomposed rank: its particles now, with room for arrivals (prepare_capture
    // grows it), in ID order through the directory.
    const std::size_t n = decomposed() ? static_cast<std::size_t>(b.particles) * 5 / 4 + 1024
                                       : static_cast<std::size_t>(b.particles);
    cap.particles = static_cast<int>(n);
    b.frame_capacity = n;
    if (decomposed()) {
      const std::size_t words = static_cast<std::size_t>((b.global_particles + 31) / 32);
      b.id_bits.allocate(std::max<std::size_t>(words, 1));
      b.id_offset.allocate(words + 1);
      b.id_counts.allocate(words + 1);
      std::size_t temp = 0;
      FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, temp, static_cast<int*>(nullptr), static_cast<int*>(nullptr),
                                                    static_cast<int>(words) + 1, stream_));
      b.id_scan_temp.allocate(std::max<std::size_t>(temp, 1));
      cap.id_bits = b.id_bits.get();
      cap.id_offset = b.id_offset.get();
    }
    b.frame_x.allocate(3 * n);
    b.frame_columns.allocate(static_cast<std::size_t>(cap.column_count) * n);
    cap.x = b.frame_x.get();
    cap.columns = b.frame_columns.get();
    b.capture = cap;
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&b.frame_copied, cudaEventDisableTiming));
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::prepare_capture(BodyBase& b) {
  if (static_cast<std::size_t>(b.particles) > b.frame_capacity) {  // arrivals outgrew the frame: the download first
    if (b.frame_copied) FBAR_CUDA_CHECK(cudaEventSynchronize(b.frame_copied));
    const std::size_t n = static_cast<std::size_t>(b.particles) * 5 / 4 + 1024;
    b.frame_x.allocate(3 * n);
    b.frame_columns.allocate(static_cast<std::size_t>(b.capture.column_count) * n);
    b.capture.x = b.frame_x.get();
    b.capture.columns = b.frame_columns.get();
    b.capture.particles = static_cast<int>(n);
    b.frame_capacity = n;
    peak_bytes_ = std::max(peak_bytes_, device_bytes());
  }
  const int words = static_cast<int>((b.global_particles + 31) / 32);
  FBAR_CUDA_CHECK(cudaMemsetAsync(b.id_bits.get(), 0, sizeof(unsigned) * std::max(words, 1), stream_));
  b.mark_ids(*this);
  count_id_bits<<<cuda::grid_for(words + 1, kOutputThreads), kOutputThreads, 0, stream_>>>(
      b.id_bits.get(), words, b.id_counts.get());
  cuda::check_launch("count_id_bits");
  std::size_t temp = b.id_scan_temp.size();
  FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(b.id_scan_temp.get(), temp, b.id_counts.get(), b.id_offset.get(),
                                                words + 1, stream_));
  b.captured_particles = b.particles;
}

template <typename T, typename TG>
std::vector<T> MgspBenchmark<T, TG>::gather_host(int body, cudaStream_t s) const {
  BodyBase& b = body_at(body);
  const int W = b.stored_scalars() + kAuxScalars;
  // By ID over the whole body; a decomposed rank holds some IDs only (the others stay NaN: all bits set).
  const std::size_t n = static_cast<std::size_t>(b.global_particles) * W;
  cuda::DeviceArray<T> out;
  out.allocate(std::max<std::size_t>(n, 1));
  if (decomposed() && n) FBAR_CUDA_CHECK(cudaMemsetAsync(out.get(), 0xff, sizeof(T) * n, s));
  FBAR_CUDA_CHECK(cudaMemsetAsync(missing_d_.get(), 0, sizeof(int), s));
  auto* self = const_cast<MgspBenchmark*>(this);
  b.gather(*self, out.get(), nullptr, missing_d_.get(), s, 0, static_cast<int>(b.global_particles));
  std::vector<T> host(n);
  int missing = 0;
  if (n) FBAR_CUDA_CHECK(cudaMemcpyAsync(host.data(), out.get(), sizeof(T) * n, cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&missing, missing_d_.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
  if (missing) throw std::runtime_error("GpuEngine: " + std::to_string(missing) + " particles with an invalid ID");
  return host;
}

template <typename T, typename TG>
ParticleSnapshot<T> MgspBenchmark<T, TG>::snapshot(int body) const {
  BodyBase& b = body_at(body);
  const std::vector<T> r = gather_host(body, stream_);
  const int S = b.stored_scalars();
  const int W = S + kAuxScalars;
  ParticleSnapshot<T> snap;
  const std::size_t n = static_cast<std::size_t>(b.global_particles);
  if (decomposed()) snap.present.assign(n, 0);
  snap.x.resize(n);
  snap.v.resize(n);
  snap.C.resize(n);
  snap.J.resize(n);
  snap.jbar.resize(n);
  snap.sigma.resize(n);
  if (b.stores_F()) snap.F.resize(n);
  if (b.stores_logJp()) snap.logJp.resize(n);
  if (b.stores_pore_pressure()) snap.pore_pressure.assign(n, std::numeric_limits<T>::quiet_NaN());
  const bool initial = steps_ == 0 && !aux_valid_;  // before the first step: v = initial velocity, C = 0 exactly
  const Vec3<T> v0{{static_cast<T>(b.spec.velocity[0]), static_cast<T>(b.spec.velocity[1]),
                    static_cast<T>(b.spec.velocity[2])}};
  for (std::size_t p = 0; p < n; ++p) {
    const T* q = r.data() + p * W;
    if (decomposed()) {
      if (std::isnan(q[0])) continue;
      snap.present[p] = 1;
    }
    snap.x[p] = Vec3<T>{{q[0], q[1], q[2]}};
    snap.v[p] = !initial ? Vec3<T>{{q[S], q[S + 1], q[S + 2]}} : b.initial_v_host.empty() ? v0 : b.initial_v_host[p];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) snap.C[p](i, j) = q[S + 3 + 3 * i + j];
    Mat3<T> F = Mat3<T>::identity(), sigma;
    T logJp = T(0);
    b.state_of(q, snap.J[p], F, sigma, logJp, snap.C[p]);
    snap.jbar[p] = b.jbar_of(q);
    snap.sigma[p] = sigma;
    if (b.stores_F()) snap.F[p] = F;
    if (b.stores_logJp()) snap.logJp[p] = logJp;
    if (b.stores_pore_pressure()) snap.pore_pressure[p] = static_cast<T>(b.pore_pressure_of(q));
  }
  return snap;
}

template <typename T, typename TG>
io::ParticleFrame MgspBenchmark<T, TG>::frame(int body) const {
  const BodyBase& b = body_at(body);
  ParticleSnapshot<T> s = snapshot(body);
  // A decomposed rank's frame: its particles only, in ID order, with their IDs.
  std::vector<std::int64_t> ids;
  if (!s.present.empty()) {
    std::size_t w = 0;
    for (std::size_t p = 0; p < s.present.size(); ++p) {
      if (!s.present[p]) continue;
      ids.push_back(static_cast<std::int64_t>(p));
      s.x[w] = s.x[p];
      s.v[w] = s.v[p];
      s.C[w] = s.C[p];
      s.J[w] = s.J[p];
      s.jbar[w] = s.jbar[p];
      s.sigma[w] = s.sigma[p];
      if (!s.F.empty()) s.F[w] = s.F[p];
      if (!s.logJp.empty()) s.logJp[w] = s.logJp[p];
      if (!s.pore_pressure.empty()) s.pore_pressure[w] = s.pore_pressure[p];
      ++w;
    }
    for (auto* v : {&s.x, &s.v}) v->resize(w);
    for (auto* v : {&s.C, &s.sigma}) v->resize(w);
    s.J.resize(w);
    s.jbar.resize(w);
    if (!s.F.empty()) s.F.resize(w);
    if (!s.logJp.empty()) s.logJp.resize(w);
    if (!s.pore_pressure.empty()) s.pore_pressure.resize(w);
  }
  FrameSource<T> src;
  if (!s.present.empty()) src.id = &ids;
  src.x = &s.x;
  src.v = &s.v;
  // A mesh is whole on its rank: entry i is vertex i.
  src.mass = [&](std::size_t i) { return b.mass_of(i); };
  src.volume0 = [&](std::size_t i) { return b.volume_of(i); };
  src.J = [&] { return s.J; };
  src.jbar = [&] { return s.jbar; };
  src.F = [&] {
    if (!b.stores_F()) throw std::invalid_argument("DefGrad: the body's material stores no deformation gradient");
    return s.F;
  };
  src.logJp = [&] {
    if (!b.stores_logJp()) throw std::invalid_argument("logJp: the body's material stores no plastic state");
    return s.logJp;
  };
  src.sigma = [&] { return s.sigma; };  // from the state and the recorded C (snapshot)
  src.pore_pressure = [&] {
    if (!b.stores_pore_pressure()) throw std::invalid_argument("PorePressure: the body's material has no pore water");
    return s.pore_pressure;
  };
  return build_frame(b.spec, body, src, "GPU engine");
}

/// Waits until the writer thread has released body b's pinned frame buffer (rethrowing a writer error meanwhile),
/// then holds it; the wait counts as output wait.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::wait_for_frame_slot(BodyBase& b, io::AsyncWriter& writer) {
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(b.frame_slot->mutex);
  while (b.frame_slot->busy) {
    b.frame_slot->released.wait_for(lock, std::chrono::milliseconds(50));
    if (b.frame_slot->busy && writer.failed()) {
      lock.unlock();
      writer.flush();  // rethrows the writer's error
      lock.lock();
    }
  }
  b.frame_slot->busy = true;
  output_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::wait_for_device_frame(BodyBase& b) {
  if (!b.frame_slot) return;
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(b.frame_slot->mutex);
  b.frame_slot->released.wait(lock, [&] { return !b.frame_slot->device; });
  output_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// A .bgeo frame without the exterior filter: pack_bgeo_records writes the file's point records into the pinned
/// buffer (mapped) on the copy stream, and the writer thread only writes them out. n entries; words: the ID
/// directory's words of a decomposed rank (by_directory), 0 otherwise.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::submit_bgeo_records(BodyBase& b, const std::filesystem::path& path, io::AsyncWriter& writer,
                                               std::size_t n, std::size_t words, bool by_directory) {
  auto* host = static_cast<std::byte*>(b.frame_host.get());
  const std::size_t record_bytes = 4 * (4 + b.frame_attrs.size());
  BgeoPack<T> pack;
  pack.x = b.frame_x.get();
  pack.columns = b.frame_columns.get();
  pack.stride = static_cast<std::size_t>(b.capture.particles);
  pack.entries = static_cast<int>(n);
  if (by_directory) {
    pack.id_bits = b.id_bits.get();
    pack.id_offset = b.id_offset.get();
    pack.words = static_cast<int>(words);
  }
  pack.attributes = static_cast<int>(b.frame_attrs.size());
  std::vector<io::BgeoAttribute> dictionary;
  int column = 0;
  for (std::size_t a = 0; a < b.frame_attrs.size(); ++a) {
    const bool id = b.frame_attrs[a].column.quantity == FrameQuantity::Id;
    pack.source[a] = id ? -1 : column++;
    dictionary.push_back({b.frame_attrs[a].name, 1, id ? io::detail::kHoudiniInt : io::detail::kHoudiniFloat});
  }
  unsigned* out = nullptr;
  FBAR_CUDA_CHECK(cudaHostGetDevicePointer(reinterpret_cast<void**>(&out), host, 0));
  if (n) {
    pack_bgeo_records<T><<<64, kOutputThreads, 0, copy_stream_>>>(pack, out);
    cuda::check_launch("pack_bgeo_records");
  }
  FBAR_CUDA_CHECK(cudaEventRecord(b.frame_copied, copy_stream_));
  const cudaEvent_t copied = b.frame_copied;
  const std::shared_ptr<typename BodyBase::HostSlot> slot = b.frame_slot;
  writer.submit_job([=] {
    const typename BodyBase::HostSlot::Hold hold{slot};  // released once written
    const auto t0 = std::chrono::steady_clock::now();
    FBAR_CUDA_CHECK(cudaEventSynchronize(copied));
    const auto t1 = std::chrono::steady_clock::now();
    io::write_bgeo_records(path, n, dictionary, reinterpret_cast<const char*>(host));
    if (std::getenv("FBAR_OUTPUT_TIMING")) {  // the writer's phases, for the output benchmark
      const auto t2 = std::chrono::steady_clock::now();
      const double wait = std::chrono::duration<double>(t1 - t0).count();
      const double write = std::chrono::duration<double>(t2 - t1).count();
      std::fprintf(stderr, "fbar: output timing: %s: records on the host after %.3f s, written in %.3f s (%.2f GB/s)\n",
                   path.filename().string().c_str(), wait, write, 1e-9 * static_cast<double>(n * record_bytes) / write);
    }
  });
}

/// The IDs of a frame's entries: a decomposed rank's are the set bits of its ID directory (one bit per ID of the
/// body, ascending), the others' the entry index (one GPU writes its frames in ID order). An index of every 64th
/// word's first entry finds the entry a read starts at.
class IdDirectory {
 public:
  IdDirectory(const unsigned* bits, std::size_t words, std::size_t entries) : bits_(bits), words_(words), n_(entries) {
    if (!words_) return;
    std::size_t k = 0;
    for (std::size_t w = 0; w < words_; ++w) {
      if (w % kStride == 0) first_.push_back(k);
      k += static_cast<std::size_t>(__builtin_popcount(bits_[w]));
    }
  }
  void read(std::size_t first, std::size_t count, std::int32_t* out) const {
    if (count == 0) return;
    if (!words_) {
      for (std::size_t i = 0; i < count; ++i) out[i] = static_cast<std::int32_t>(first + i);
      return;
    }
    if (first + count > n_) throw std::logic_error("IdDirectory: entries past the frame");
    std::size_t g = static_cast<std::size_t>(std::upper_bound(first_.begin(), first_.end(), first) - first_.begin()) - 1;
    std::size_t k = first_[g], w = g * kStride;
    for (; k + static_cast<std::size_t>(__builtin_popcount(bits_[w])) <= first; ++w)
      k += static_cast<std::size_t>(__builtin_popcount(bits_[w]));
    std::size_t done = 0;
    for (; w < words_ && done < count; ++w)
      for (unsigned m = bits_[w]; m != 0 && done < count; m &= m - 1, ++k)
        if (k >= first) out[done++] = static_cast<std::int32_t>(32 * w + static_cast<std::size_t>(__builtin_ctz(m)));
  }

 private:
  static constexpr std::size_t kStride = 64;
  const unsigned* bits_;
  std::size_t words_, n_;
  std::vector<std::size_t> first_;  ///< entries before word kStride x g
};

/// Per frame attribute: its device column, or -1 for ID (from the directory).
inline std::vector<int> frame_column_of(const std::vector<FrameAttributeSpec>& attrs) {
  std::vector<int> of;
  int column = 0;
  for (const FrameAttributeSpec& a : attrs) of.push_back(a.column.quantity == FrameQuantity::Id ? -1 : column++);
  return of;
}

/// A captured frame's stream without its readers: n entries, positions in T, the attributes (width 1; ID int32).
template <typename T>
io::FrameStream frame_stream(const std::vector<FrameAttributeSpec>& attrs, std::size_t n,
                             const io::ExteriorFilter& exterior) {
  io::FrameStream s;
  s.points = n;
  s.double_precision = std::is_same_v<T, double>;
  s.exterior = exterior;
  for (const FrameAttributeSpec& a : attrs) {
    const bool id = a.column.quantity == FrameQuantity::Id;
    s.attributes.push_back({a.name, 1, id ? std::string() : a.unit, id ? io::AttributeType::Int : io::AttributeType::Float});
  }
  return s;
}

/// A mesh's frame in memory (its vertices are few) from its stream, with the tetrahedra its .vtk is written from.
template <typename T>
io::ParticleFrame mesh_frame(const io::FrameStream& s, const std::vector<FrameAttributeSpec>& attrs,
                             const std::vector<int>& column_of,
                             const std::shared_ptr<const std::vector<std::array<int, 4>>>& tetrahedra) {
  const std::size_t n = s.points;
  io::ParticleFrame f;
  f.exterior = s.exterior;
  f.tetrahedra = tetrahedra;
  std::vector<Vec3<T>> positions(n);
  s.read_positions(0, n, positions.data());
  f.positions = std::move(positions);
  for (std::size_t a = 0; a < attrs.size(); ++a) {
    if (column_of[a] < 0) {
      std::vector<std::int32_t> v(n);
      s.read_values(a, 0, n, v.data());
      f.add(attrs[a].name, 1, std::move(v));
    } else {
      std::vector<float> v(n);
      s.read_values(a, 0, n, v.data());
      f.add(attrs[a].name, 1, std::move(v), attrs[a].unit);
    }
  }
  return f;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer) {
  // The frame is on the device already (the capture step, or capture_state before the first step). Its download
  // runs on the copy stream into the body's pinned buffer, which the writer thread turns into the file; the step
  // loop waits only when that buffer is still being read from the previous frame (output slower than simulation).
  BodyBase& b = body_at(body);
  if (!b.capture.x)
    throw std::logic_error("GpuEngine::submit_frame: frames were not planned (GpuEngineOptions::frames)");
  if (captured_step_ != steps_) {
    if (steps_ != 0 || captured_step_ >= 0)
      throw std::logic_error("GpuEngine::submit_frame: step " + std::to_string(steps_) +
                             " did not capture a frame (set_frame_capture(true) before the step that lands on it)");
    if (decomposed()) prepare_capture(b);
    b.capture_state(*this);
  }
  wait_for_frame_slot(b, writer);
  const bool by_directory = decomposed();
  const std::size_t n = static_cast<std::size_t>(by_directory ? b.captured_particles : b.particles);
  const int columns = b.capture.column_count;
  const std::size_t words = by_directory ? static_cast<std::size_t>((b.global_particles + 31) / 32) : 0;
  const io::ExteriorFilter exterior = exterior_filter(scene_, body);
  const std::size_t record_bytes = 4 * (4 + b.frame_attrs.size());
  const std::size_t whole_bytes = n * (3 * sizeof(T) + sizeof(float) * columns) + words * sizeof(unsigned);
  // A frame whose download fits GpuEngineOptions::frame_host_bytes comes down whole into the body's pinned buffer
  // and the device frame is free at once; a larger one is streamed: the writer reads it from the device a piece at
  // a time through a pinned buffer of one piece's positions (or frame_host_bytes if less), and the next capture
  // waits until it has (host memory O(piece), whatever the particle count).
  // A mesh's frame always comes down whole (the .vtk of its tetrahedra needs every vertex).
  const bool whole = b.mesh || whole_bytes <= options_.frame_host_bytes;
  // A whole .bgeo frame without the exterior filter: the GPU writes the file's point records into the pinned
  // buffer (pack_bgeo_records) and the writer thread only writes them out.
  const bool records = whole && !b.mesh && path.extension() == ".bgeo" && !exterior.on() &&
                       b.frame_attrs.size() <= static_cast<std::size_t>(kMaxFrameColumns) + 1;
  // Streamed: a piece's positions at most (the writers read io::FrameStream::piece points at a time).
  const std::size_t stream_bytes = std::max<std::size_t>(
      std::min<std::size_t>(options_.frame_host_bytes, io::kFramePiecePoints * 3 * sizeof(T)), 3 * sizeof(T));
  const std::size_t host_bytes = records ? n * record_bytes : whole ? whole_bytes : stream_bytes;
  if (!b.frame_host || b.frame_host_size < host_bytes) {  // the writer has released it (busy was false)
    b.frame_host = cuda::pinned(std::max<std::size_t>(host_bytes, 1));
    b.frame_host_size = std::max<std::size_t>(host_bytes, 1);
  }
  cudaEvent_t ready;
  FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&ready, cudaEventDisableTiming));
  FBAR_CUDA_CHECK(cudaEventRecord(ready, stream_));
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(copy_stream_, ready, 0));
  FBAR_CUDA_CHECK(cudaEventDestroy(ready));
  auto* host = static_cast<std::byte*>(b.frame_host.get());
  if (records) {
    submit_bgeo_records(b, path, writer, n, words, by_directory);
    return;
  }
  const std::shared_ptr<typename BodyBase::HostSlot> slot = b.frame_slot;
  const std::vector<FrameAttributeSpec> attrs = b.frame_attrs;
  const io::FrameStream layout = frame_stream<T>(b.frame_attrs, n, exterior);
  if (!whole) {  // the writer reads the device frame, on the copy stream, until it has written the file
    {
      std::lock_guard<std::mutex> lock(slot->mutex);
      slot->device = true;
    }
    int device = 0;
    FBAR_CUDA_CHECK(cudaGetDevice(&device));
    const T* x_d = b.frame_x.get();
    const float* columns_d = b.frame_columns.get();
    const std::size_t stride = static_cast<std::size_t>(b.capture.particles);
    const unsigned* bits_d = b.id_bits.get();
    const cudaStream_t copy = copy_stream_;
    const std::size_t buffer = host_bytes;
    writer.submit_job([=] {
      const typename BodyBase::HostSlot::Hold hold{slot};  // the pinned buffer and the device frame, until written
      FBAR_CUDA_CHECK(cudaSetDevice(device));
      auto fetch = [&](const void* from, std::size_t bytes, void* out) {
        for (std::size_t done = 0; done < bytes; done += buffer) {
          const std::size_t part = std::min(buffer, bytes - done);
          FBAR_CUDA_CHECK(cudaMemcpyAsync(host, static_cast<const std::byte*>(from) + done, part,
                                          cudaMemcpyDeviceToHost, copy));
          FBAR_CUDA_CHECK(cudaStreamSynchronize(copy));
          std::memcpy(static_cast<std::byte*>(out) + done, host, part);
        }
      };
      std::vector<unsigned> bits(words);  // a decomposed rank's ID directory: 4 B per 32 IDs of the body
      if (words) fetch(bits_d, words * sizeof(unsigned), bits.data());
      io::FrameStream s = layout;
      s.read_positions = [&](std::size_t first, std::size_t count, void* out) {
        fetch(x_d + 3 * first, 3 * count * sizeof(T), out);
      };
      const IdDirectory ids(bits.data(), words, n);
      const std::vector<int> column_of = frame_column_of(attrs);
      s.read_values = [&](std::size_t a, std::size_t first, std::size_t count, void* out) {
        if (column_of[a] < 0) return ids.read(first, count, static_cast<std::int32_t*>(out));
        fetch(columns_d + static_cast<std::size_t>(column_of[a]) * stride + first, count * sizeof(float), out);
      };
      io::write_frame(path, s);
    });
    return;
  }
  if (n) {
    FBAR_CUDA_CHECK(cudaMemcpyAsync(host, b.frame_x.get(), 3 * n * sizeof(T), cudaMemcpyDeviceToHost, copy_stream_));
    // Column c of the device frame starts at c x capture.particles (a decomposed rank's frame has room for
    // arrivals); the host copy packs them at c x n.
    if (columns)
      FBAR_CUDA_CHECK(cudaMemcpy2DAsync(host + 3 * n * sizeof(T), n * sizeof(float), b.frame_columns.get(),
                                        static_cast<std::size_t>(b.capture.particles) * sizeof(float),
                                        n * sizeof(float), static_cast<std::size_t>(columns), cudaMemcpyDeviceToHost,
                                        copy_stream_));
  }
  if (words)  // the IDs of the rank's entries: the directory's set bits, in order
    FBAR_CUDA_CHECK(cudaMemcpyAsync(host + n * (3 * sizeof(T) + sizeof(float) * columns), b.id_bits.get(),
                                    words * sizeof(unsigned), cudaMemcpyDeviceToHost, copy_stream_));
  FBAR_CUDA_CHECK(cudaEventRecord(b.frame_copied, copy_stream_));
  const cudaEvent_t copied = b.frame_copied;
  std::shared_ptr<const std::vector<std::array<int, 4>>> tetrahedra;
  if (b.mesh) {
    const std::shared_ptr<const TetMesh>& mesh = scene_.meshes[static_cast<std::size_t>(b.spec.mesh)].mesh;
    tetrahedra = std::shared_ptr<const std::vector<std::array<int, 4>>>(mesh, &mesh->elements);
  }
  writer.submit_job([=] {
    const typename BodyBase::HostSlot::Hold hold{slot};  // the pinned buffer, until written
    FBAR_CUDA_CHECK(cudaEventSynchronize(copied));
    // The frame is read straight out of the pinned buffer: positions, then the columns, then the ID directory.
    const T* x = reinterpret_cast<const T*>(host);
    const float* col = reinterpret_cast<const float*>(host + 3 * n * sizeof(T));
    const IdDirectory ids(reinterpret_cast<const unsigned*>(host + n * (3 * sizeof(T) + sizeof(float) * columns)),
                          words, n);
    const std::vector<int> column_of = frame_column_of(attrs);
    io::FrameStream s = layout;
    s.read_positions = [&](std::size_t first, std::size_t count, void* out) {
      std::memcpy(out, x + 3 * first, 3 * count * sizeof(T));
    };
    s.read_values = [&](std::size_t a, std::size_t first, std::size_t count, void* out) {
      if (column_of[a] < 0) return ids.read(first, count, static_cast<std::int32_t*>(out));
      std::memcpy(out, col + static_cast<std::size_t>(column_of[a]) * n + first, count * sizeof(float));
    };
    if (!tetrahedra) return io::write_frame(path, s);
    io::write_frame(path, mesh_frame<T>(s, attrs, column_of, tetrahedra));  // with the .vtk of its tetrahedra
  });
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::total_mass() const {
  double m = 0.0;
  for (const auto& b : bodies_) {
    if (!b->mesh) {
      m += static_cast<double>(b->particles) * static_cast<double>(b->mass);
    } else if (b->particles > 0) {  // the rank holding the mesh: its lumped vertex masses
      for (const T mv : b->mesh->mass) m += static_cast<double>(mv);
    }
  }
  return m;
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::elastic_energy() const {
  double e = 0.0;
  for (int body = 0; body < body_count(); ++body) {
    const BodyBase& b = body_at(body);
    if (b.mesh) {  // the elements' energy (as the CPU engine), on the rank holding them
      if (b.mesh->on_device()) e += mesh_energy(b);
      continue;
    }
    const std::vector<T> r = gather_host(body, stream_);
    const int W = b.stored_scalars() + kAuxScalars;
    for (std::size_t p = 0; p < static_cast<std::size_t>(b.global_particles); ++p)
      if (!decomposed() || !std::isnan(r[p * W]))
        e += static_cast<double>(b.volume) * b.energy_density_of(r.data() + p * W);
  }
  return e;
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::mesh_energy(const BodyBase& b) const {
  // The gradients the element pass left (MeshDevice::F, F-bar's when use_FBAR): those of the committed positions,
  // since every try ends with its pass and a committed step's last try is the committed one (after a step that
  // returned a failure: the failed try's).
  std::vector<Mat3<T>> F(b.mesh->host.elements.size());
  if (!F.empty()) {
    FBAR_CUDA_CHECK(cudaMemcpyAsync(F.data(), b.mesh->F.get(), sizeof(Mat3<T>) * F.size(), cudaMemcpyDeviceToHost,
                                    stream_));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  }
  double e = 0.0;
  for (std::size_t k = 0; k < F.size(); ++k)
    e += static_cast<double>(b.mesh->host.elements[k].volume) * b.element_energy_density(F[k]);
  return e;
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::grid_mass() const {
  using View = typename GridBuffer<TG>::View;
  std::vector<unsigned long long> host(View::kBlockWords * static_cast<std::size_t>(block_count_));
  if (!host.empty())
    FBAR_CUDA_CHECK(cudaMemcpy(host.data(), grid_sums(gc_).data(), sizeof(unsigned long long) * host.size(),
                               cudaMemcpyDeviceToHost));
  GridQuantum q;
  FBAR_CUDA_CHECK(cudaMemcpy(&q, quantum(gc_), sizeof(q), cudaMemcpyDeviceToHost));
  const View view{host.data()};
  double m = 0.0;
  for (int b = 0; b < block_count_; ++b)
    for (int n = 0; n < 64; ++n) m += static_cast<double>(static_cast<TG>(view.units(b, kSumMass, n) * q.mass));
  return m;
}

template <typename T, typename TG>
std::size_t MgspBenchmark<T, TG>::particle_blocks() const {
  if (block_count_ == 0) return 0;
  cuda::DeviceArray<int> flags;  // zeroed
  flags.allocate(static_cast<std::size_t>(block_count_) + 1);
  for (const auto& b : bodies_)
    mark_particle_blocks<<<cuda::grid_for(block_count_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        b->partition.layout(cur_).count, block_count_, flags.get());
  count_flags<<<cuda::grid_for(block_count_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(flags.get(),
                                                                                               block_count_);
  cuda::check_launch("count_flags");
  int n = 0;
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&n, flags.get() + block_count_, sizeof(int), cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  return static_cast<std::size_t>(n);
}

template <typename T, typename TG>
std::size_t MgspBenchmark<T, TG>::device_bytes() const {
  std::size_t bytes = table_.bytes() + channels_.bytes() +
                      stats_bytes_.bytes() + wave_d_.bytes() + p2g_bound_d_.bytes() + scan_temp_.bytes() +
                      sensors_.grid_samples_d.bytes() + sensors_.particle_samples_d.bytes() + sensors_.partials_d.bytes() +
                      sensors_.track_d.bytes();
  for (const auto& b : bodies_) {
    bytes += b->bins_bytes() + b->partition.bytes() + b->aux.bytes() + b->frame_x.bytes() + b->frame_columns.bytes();
    if (b->mesh) bytes += b->mesh->device_bytes();
  }
  return bytes;
}

}  // namespace fbar
