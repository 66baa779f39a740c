// Embree throughput benchmark. Compiles against Embree 3 (-DE3) or Embree 4 (default).
// usage: embree_bench MESH RAYS THREADS MODE [reps [shadow]]   MODE = 1 | 4 | 8 | 16 | 1M (1M: Embree 3 stream API only)
// With `shadow`, the rays traced are the shadow rays of RAYS (any hit, rtcOccluded1/4/8/16): ray i runs from the
// closest hit of ray i (rtcIntersect1, untimed), pulled back toward the ray's origin by 0.1 % of the hit distance,
// p = o + 0.999 t d, toward the light L = (3, 1, -2): direction (L - p)/|L - p|, tfar = |L - p|, computed in double
// and rounded to float; rays that missed have no shadow ray (an invalid packet lane). The line then says
// rays=RAYS.shadow, Mrays/s counts the shadow rays, hits is the fraction blocked and mean_t the mean tfar.
// This is the set octaray's bench-trace traces (src/bvh/bench.rs, `shadow_rays`).
#if defined(E3)
#include <embree3/rtcore.h>
#else
#include <embree4/rtcore.h>
#endif
#include <xmmintrin.h>
#include <pmmintrin.h>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>
using clk = std::chrono::steady_clock;
static double secs(clk::time_point a, clk::time_point b) { return std::chrono::duration<double>(b - a).count(); }

struct Mesh { std::vector<float> v; std::vector<unsigned> t; };
static Mesh load_mesh(const char* p) {
  FILE* f = fopen(p, "rb"); unsigned n[2]; if (!f || fread(n, 4, 2, f) != 2) { perror(p); exit(1); }
  Mesh m; m.v.resize(n[0] * 3); m.t.resize(n[1] * 3);
  if (fread(m.v.data(), 4, m.v.size(), f) != m.v.size() || fread(m.t.data(), 4, m.t.size(), f) != m.t.size()) exit(1);
  fclose(f); return m;
}
static std::vector<float> load_rays(const char* p) {
  FILE* f = fopen(p, "rb"); unsigned n; if (!f || fread(&n, 4, 1, f) != 1) { perror(p); exit(1); }
  std::vector<float> r(size_t(n) * 6); if (fread(r.data(), 4, r.size(), f) != r.size()) exit(1); fclose(f); return r;
}

static RTCScene build(RTCDevice dev, const Mesh& m) {
  RTCScene s = rtcNewScene(dev);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  size_t nv = m.v.size() / 3, nt = m.t.size() / 3;
  float* vb = (float*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, nv);
  unsigned* ib = (unsigned*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, nt);
  memcpy(vb, m.v.data(), nv * 12); memcpy(ib, m.t.data(), nt * 12);
  rtcCommitGeometry(g); rtcAttachGeometry(s, g); rtcReleaseGeometry(g);
  rtcCommitScene(s);
  return s;
}

int main(int argc, char** argv) {
  if (argc < 5) { fprintf(stderr, "usage: %s MESH RAYS THREADS MODE [reps]\n", argv[0]); return 1; }
  Mesh m = load_mesh(argv[1]); std::vector<float> R = load_rays(argv[2]);
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON); _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  int T = atoi(argv[3]); std::string mode = argv[4]; int reps = argc > 5 ? atoi(argv[5]) : 5;
  bool shadow = argc > 6 && std::string(argv[6]) == "shadow";
  bool coherent = strstr(argv[2], "primary") != nullptr;
  size_t N = R.size() / 6;
  char cfg[64]; snprintf(cfg, sizeof cfg, "threads=%d", T);
  RTCDevice dev = rtcNewDevice(cfg);
  // build time: build once to warm up the thread pool, then best of 3
  rtcReleaseScene(build(dev, m));
  double bbest = 1e9; RTCScene s = nullptr;
  for (int i = 0; i < 3; i++) { if (s) rtcReleaseScene(s); auto a = clk::now(); s = build(dev, m); bbest = std::min(bbest, secs(a, clk::now())); }

  std::vector<float> tout(N);
  std::vector<unsigned> pout(N);
  // shadow rays: R rewritten in place, tmax per ray (0: none)
  std::vector<float> tmax;
  if (shadow) {
#if defined(E3)
    RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
#else
    RTCIntersectArguments args; rtcInitIntersectArguments(&args);
#endif
    const double L[3] = {3.0, 1.0, -2.0};
    tmax.assign(N, 0.f);
    for (size_t i = 0; i < N; i++) {
      RTCRayHit rh; float* r = &R[i * 6];
      rh.ray.org_x = r[0]; rh.ray.org_y = r[1]; rh.ray.org_z = r[2];
      rh.ray.dir_x = r[3]; rh.ray.dir_y = r[4]; rh.ray.dir_z = r[5];
      rh.ray.tnear = 0; rh.ray.tfar = INFINITY; rh.ray.mask = ~0u; rh.ray.flags = 0; rh.ray.time = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID; rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
#if defined(E3)
      rtcIntersect1(s, &ctx, &rh);
#else
      rtcIntersect1(s, &rh, &args);
#endif
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      double t = 0.999 * double(rh.ray.tfar), p[3], v[3];
      for (int a = 0; a < 3; a++) { p[a] = double(r[a]) + double(r[3 + a]) * t; v[a] = L[a] - p[a]; }
      double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      for (int a = 0; a < 3; a++) { r[a] = float(p[a]); r[3 + a] = float(v[a] / len); }
      tmax[i] = float(len);
    }
  }
  std::vector<unsigned char> blocked(N);
  const size_t CH = 4096;  // rays per work item (multiple of 16)
  auto trace_range = [&](size_t b, size_t e) {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON); _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#if defined(E3)
    RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
    ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
#define ISECT1(rh) rtcIntersect1(s, &ctx, &rh)
#define ISECTN(n, v, rh) rtcIntersect##n(v, s, &ctx, &rh)
#else
    RTCIntersectArguments args; rtcInitIntersectArguments(&args);
    args.flags = coherent ? RTC_RAY_QUERY_FLAG_COHERENT : RTC_RAY_QUERY_FLAG_INCOHERENT;
#define ISECT1(rh) rtcIntersect1(s, &rh, &args)
#define ISECTN(n, v, rh) rtcIntersect##n(v, s, &rh, &args)
#endif
    // shadow ray i as one RTCRay (modes 1 and 1M)
    auto shadow_ray = [&](size_t i) {
      RTCRay ray; const float* r = &R[i * 6];
      ray.org_x = r[0]; ray.org_y = r[1]; ray.org_z = r[2]; ray.dir_x = r[3]; ray.dir_y = r[4]; ray.dir_z = r[5];
      ray.tnear = 0; ray.tfar = tmax[i]; ray.mask = ~0u; ray.flags = 0; ray.time = 0;
      return ray;
    };
    if (shadow && mode == "1") {
      for (size_t i = b; i < e; i++) {
        blocked[i] = 0;
        if (!(tmax[i] > 0)) continue;
        RTCRay ray = shadow_ray(i);
#if defined(E3)
        rtcOccluded1(s, &ctx, &ray);
#else
        rtcOccluded1(s, &ray, (RTCOccludedArguments*)nullptr);
#endif
        blocked[i] = ray.tfar < 0;
      }
    }
#if defined(E3)
#define OCCLN(n, v, r) rtcOccluded##n(v, s, &ctx, &r)
#else
#define OCCLN(n, v, r) rtcOccluded##n(v, s, &r, (RTCOccludedArguments*)nullptr)
#endif
#define SHADOW_PACKET(W, RT)                                                              \
    else if (shadow && mode == #W) {                                                      \
      for (size_t i = b; i < e; i += W) {                                                 \
        alignas(64) int valid[W]; alignas(64) RT ray; int any = 0;                        \
        for (int k = 0; k < W; k++) { const float* r = &R[(i + k) * 6];                   \
          valid[k] = tmax[i + k] > 0 ? -1 : 0; any |= valid[k];                           \
          ray.org_x[k] = r[0]; ray.org_y[k] = r[1]; ray.org_z[k] = r[2];                  \
          ray.dir_x[k] = r[3]; ray.dir_y[k] = r[4]; ray.dir_z[k] = r[5];                  \
          ray.tnear[k] = 0; ray.tfar[k] = tmax[i + k]; ray.mask[k] = ~0u;                 \
          ray.flags[k] = 0; ray.time[k] = 0; }                                            \
        if (any) OCCLN(W, valid, ray);                                                    \
        for (int k = 0; k < W; k++) blocked[i + k] = valid[k] && ray.tfar[k] < 0;         \
      }                                                                                   \
    }
    SHADOW_PACKET(4, RTCRay4)
    SHADOW_PACKET(8, RTCRay8)
    SHADOW_PACKET(16, RTCRay16)
#if defined(E3)
    else if (shadow && mode == "1M") {
      // the stream of the range's shadow rays (those with one), rtcOccluded1M
      std::vector<RTCRay> ray; std::vector<size_t> at;
      for (size_t i = b; i < e; i++) {
        blocked[i] = 0;
        if (!(tmax[i] > 0)) continue;
        ray.push_back(shadow_ray(i)); at.push_back(i);
      }
      if (!ray.empty()) rtcOccluded1M(s, &ctx, ray.data(), unsigned(ray.size()), sizeof(RTCRay));
      for (size_t k = 0; k < ray.size(); k++) blocked[at[k]] = ray[k].tfar < 0;
    }
#endif
    else if (shadow) { fprintf(stderr, "bad shadow mode\n"); exit(1); }
    else if (mode == "1") {
      for (size_t i = b; i < e; i++) {
        RTCRayHit rh; const float* r = &R[i * 6];
        rh.ray.org_x = r[0]; rh.ray.org_y = r[1]; rh.ray.org_z = r[2];
        rh.ray.dir_x = r[3]; rh.ray.dir_y = r[4]; rh.ray.dir_z = r[5];
        rh.ray.tnear = 0; rh.ray.tfar = INFINITY; rh.ray.mask = ~0u; rh.ray.flags = 0; rh.ray.time = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID; rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        ISECT1(rh);
        tout[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1.f : rh.ray.tfar; pout[i] = rh.hit.primID;
      }
    }
#define PACKET(W, RH)                                                                     \
    else if (mode == #W) {                                                                \
      alignas(64) int valid[W]; for (int k = 0; k < W; k++) valid[k] = -1;                \
      for (size_t i = b; i < e; i += W) {                                                 \
        alignas(64) RH rh;                                                                \
        for (int k = 0; k < W; k++) { const float* r = &R[(i + k) * 6];                   \
          rh.ray.org_x[k] = r[0]; rh.ray.org_y[k] = r[1]; rh.ray.org_z[k] = r[2];          \
          rh.ray.dir_x[k] = r[3]; rh.ray.dir_y[k] = r[4]; rh.ray.dir_z[k] = r[5];          \
          rh.ray.tnear[k] = 0; rh.ray.tfar[k] = INFINITY; rh.ray.mask[k] = ~0u;            \
          rh.ray.flags[k] = 0; rh.ray.time[k] = 0;                                         \
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID; rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID; } \
        ISECTN(W, valid, rh);                                                             \
        for (int k = 0; k < W; k++) { tout[i + k] = rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID ? -1.f : rh.ray.tfar[k]; pout[i + k] = rh.hit.primID[k]; } \
      }                                                                                   \
    }
    PACKET(4, RTCRayHit4)
    PACKET(8, RTCRayHit8)
    PACKET(16, RTCRayHit16)
#if defined(E3)
    else if (mode == "1M") {
      std::vector<RTCRayHit> rh(e - b);
      for (size_t i = b; i < e; i++) { RTCRayHit& x = rh[i - b]; const float* r = &R[i * 6];
        x.ray.org_x = r[0]; x.ray.org_y = r[1]; x.ray.org_z = r[2]; x.ray.dir_x = r[3]; x.ray.dir_y = r[4]; x.ray.dir_z = r[5];
        x.ray.tnear = 0; x.ray.tfar = INFINITY; x.ray.mask = ~0u; x.ray.flags = 0; x.ray.time = 0;
        x.hit.geomID = RTC_INVALID_GEOMETRY_ID; x.hit.instID[0] = RTC_INVALID_GEOMETRY_ID; }
      rtcIntersect1M(s, &ctx, rh.data(), unsigned(e - b), sizeof(RTCRayHit));
      for (size_t i = b; i < e; i++) { tout[i] = rh[i - b].hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1.f : rh[i - b].ray.tfar; pout[i] = rh[i - b].hit.primID; }
    }
#endif
    else { fprintf(stderr, "bad mode\n"); exit(1); }
  };
  double best = 1e9;
  for (int rep = 0; rep < reps; rep++) {
    std::atomic<size_t> next{0};
    auto worker = [&]() { for (;;) { size_t b = next.fetch_add(CH); if (b >= N) break; trace_range(b, std::min(N, b + CH)); } };
    auto a = clk::now();
    std::vector<std::thread> th; for (int t = 1; t < T; t++) th.emplace_back(worker);
    worker(); for (auto& x : th) x.join();
    best = std::min(best, secs(a, clk::now()));
  }
  size_t hits = 0; double tsum = 0; size_t traced = N;
  if (shadow) {
    traced = 0;
    for (size_t i = 0; i < N; i++) if (tmax[i] > 0) { traced++; hits += blocked[i]; tsum += tmax[i]; }
  } else {
    for (size_t i = 0; i < N; i++) if (tout[i] >= 0) { hits++; tsum += tout[i]; }
  }
  printf("embree%s mesh=%s rays=%s%s threads=%d mode=%s tris=%zu build_ms=%.1f trace_ms=%.1f Mrays/s=%.2f hits=%.4f mean_t=%.6f\n",
         RTC_VERSION_STRING, argv[1], argv[2], shadow ? ".shadow" : "", T, mode.c_str(), m.t.size() / 3, bbest * 1e3,
         best * 1e3, traced / best / 1e6, traced ? double(hits) / traced : 0.0,
         shadow ? (traced ? tsum / traced : 0.0) : (hits ? tsum / hits : 0.0));
  rtcReleaseScene(s); rtcReleaseDevice(dev);
}
