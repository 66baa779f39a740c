// A Whitted ray tracer on Intel Embree 3: the peer of `octaray render` on mesh scenes, with the shading rules of
// docs/scene-format.md (Phong with hard shadows, mirror reflection, per-level clamping, the checkerboard floor).
//
// usage: whitted SCENE -o OUT.bmp [--eye X,Y,Z] [--look-at X,Y,Z] [--up X,Y,Z] [--fov DEG] [--size N|WxH]
//                      [--threads 1] [--floor-last]
// Camera arguments mean what they mean to `octaray render` (src/scene/camera.rs): vertical field of view in degrees,
// `up` made orthogonal to the view direction, rays through pixel centres, the window widened for non-square
// images. Defaults: the assignment's camera, the scene's `pixels` square.
//
// Supported objects: `triangle` and `mesh PATH.obj`; point lights and spotlights. Spheres, quadrics and prisms
// are rejected (exit 2). Build: g++ -O3 -march=native -fno-math-errno -std=c++17 whitted.cpp -o whitted -lembree3
// -lpthread (-O3 and no errno: the per-lane shading loops vectorize).
//
// Tracing: camera rays in 4 x 4 pixel blocks with rtcIntersect16, shadow rays per light with rtcOccluded16 (the
// lanes whose light is in front of the surface), mirror rays with rtcIntersect16 up to the recursion level (level
// N gives N - 1 bounces); the camera rays and their shadow rays go with Embree's coherent flag, the rest without.
// Embree holds the triangles; the floor (z = 0, |x|, |y| <= 500) is a plane tested beside it: it shortens a
// closest-hit ray's tfar before Embree traverses (with --floor-last it is tested after Embree's traversal, as
// octaray tests it after its tree), and blocks shadow rays before Embree is asked.
// Secondary rays start at P + eps N (N the geometric normal turned to face the incoming ray, so both shadow rays
// toward a light in front and mirror rays leave on that side), eps = 1e-4 max(1, |P|_inf).
//
// Prints one line on stderr: times (load, build, render, write) and ray counts (primary, shadow, reflection),
// counted as octaray counts them.
#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

using clk = std::chrono::steady_clock;
static double secs(clk::time_point a, clk::time_point b) { return std::chrono::duration<double>(b - a).count(); }

[[noreturn]] static void fail(const std::string& msg) {
  fprintf(stderr, "whitted: %s\n", msg.c_str());
  exit(2);
}

// ---------------------------------------------------------------------------------------------------------------
// Small vector maths

struct V3 {
  double x, y, z;
};
static V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
static V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
static V3 operator*(V3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
static double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
static double length(V3 a) { return std::sqrt(dot(a, a)); }
static V3 normalize(V3 a) { return a * (1.0 / length(a)); }

// ---------------------------------------------------------------------------------------------------------------
// Files

static std::vector<char> read_file(const std::string& path) {
  FILE* f = fopen(path.c_str(), "rb");
  if (!f) fail(path + ": cannot read: " + strerror(errno));
  std::vector<char> buf;
  // a regular file in one read of its size; anything else (a pipe) in chunks
  long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  if (n >= 0 && fseek(f, 0, SEEK_SET) == 0) {
    buf.resize(size_t(n));
    if (fread(buf.data(), 1, buf.size(), f) != buf.size()) fail(path + ": cannot read: " + strerror(errno));
  } else {
    char chunk[1 << 16];
    size_t got;
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0) buf.insert(buf.end(), chunk, chunk + got);
    if (ferror(f)) fail(path + ": cannot read: " + strerror(errno));
  }
  fclose(f);
  return buf;
}

// ---------------------------------------------------------------------------------------------------------------
// Scene file (docs/scene-format.md): whitespace-separated tokens, `//` comments, keywords case-insensitive.

struct Material {
  float r, g, b, ka, kd, ks, kr, shine;
};

struct Object {
  Material m;
};

struct Light {
  V3 pos, color;
  bool spot;
  V3 axis;        // unit spot direction
  double cos_cut; // cos(cutoff); a point is lit when cos(angle to the axis) >= cos_cut
};

struct Mesh {
  std::vector<float> v;          // x y z per vertex, plus one float of padding (Embree reads 16 bytes a vertex)
  std::vector<unsigned> t;       // 3 indices per triangle
  std::vector<unsigned> object;  // per triangle, its object (used by the loose `triangle` objects only)
};

struct Scene {
  unsigned recursion_level = 0, pixels = 0;
  std::vector<Object> objects;
  std::vector<std::pair<std::string, unsigned>> meshes;  // OBJ path (resolved), object index
  Mesh loose;                                             // all `triangle` objects, one Embree geometry
  std::vector<Light> lights;                              // point lights, then spotlights
};

class Tokens {
 public:
  Tokens(std::string name, std::vector<char> text) : name_(std::move(name)), s_(std::move(text)) { skip(); }
  bool done() const { return pos_ >= s_.size(); }
  // The next token, with its line and column for messages.
  std::string next(const std::string& field) {
    if (done()) fail(where() + field + ": expected a value, found the end of the file");
    tline_ = line_;
    tcol_ = pos_ - line_start_ + 1;
    size_t b = pos_;
    while (pos_ < s_.size() && !space(s_[pos_]) && !comment()) pos_++;
    std::string tok(s_.data() + b, pos_ - b);
    skip();
    return tok;
  }
  std::string peek() {
    size_t p = pos_;
    while (p < s_.size() && !space(s_[p]) && !(s_[p] == '/' && p + 1 < s_.size() && s_[p + 1] == '/')) p++;
    return std::string(s_.data() + pos_, p - pos_);
  }
  double number(const std::string& field) {
    std::string tok = next(field);
    char* end = nullptr;
    double v = strtod(tok.c_str(), &end);
    if (tok.empty() || *end != '\0' || !std::isfinite(v))
      fail(at() + field + ": expected a finite number, got `" + tok + "`");
    return v;
  }
  double nonneg(const std::string& field) {
    double v = number(field);
    if (v < 0) fail(at() + field + ": must be >= 0, got " + std::to_string(v));
    return v;
  }
  unsigned integer(const std::string& field, unsigned long lo, unsigned long hi) {
    std::string tok = next(field);
    unsigned long v = 0;
    auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (tok.empty() || r.ec != std::errc() || r.ptr != tok.data() + tok.size() || v < lo || v > hi)
      fail(at() + field + ": expected an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got `" +
           tok + "`");
    return unsigned(v);
  }
  // "file:line:col: " of the token just read.
  std::string at() const { return name_ + ":" + std::to_string(tline_) + ":" + std::to_string(tcol_) + ": "; }
  std::string where() const { return name_ + ":" + std::to_string(line_) + ": "; }

 private:
  static bool space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
  bool comment() const { return s_[pos_] == '/' && pos_ + 1 < s_.size() && s_[pos_ + 1] == '/'; }
  void newline() {
    line_++;
    line_start_ = pos_ + 1;
  }
  void skip() {
    while (pos_ < s_.size()) {
      char c = s_[pos_];
      if (c == '\n' || (c == '\r' && !(pos_ + 1 < s_.size() && s_[pos_ + 1] == '\n'))) {
        newline();
        pos_++;
      } else if (space(c)) {
        pos_++;
      } else if (comment()) {
        while (pos_ < s_.size() && s_[pos_] != '\n' && s_[pos_] != '\r') pos_++;
      } else {
        break;
      }
    }
  }
  std::string name_;
  std::vector<char> s_;
  size_t pos_ = 0, line_ = 1, line_start_ = 0, tline_ = 0, tcol_ = 0;
};

static std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower((unsigned char)c));
  return s;
}

static V3 read_v3(Tokens& tk, const std::string& field) {
  double x = tk.number(field + " x"), y = tk.number(field + " y"), z = tk.number(field + " z");
  return {x, y, z};
}

static Scene parse_scene(const std::string& path) {
  std::vector<char> text = read_file(path);
  if (text.size() >= 3 && (unsigned char)text[0] == 0xef && (unsigned char)text[1] == 0xbb &&
      (unsigned char)text[2] == 0xbf)
    text.erase(text.begin(), text.begin() + 3);
  Tokens tk(path, std::move(text));
  std::string dir = path.find('/') == std::string::npos ? "" : path.substr(0, path.rfind('/') + 1);
  Scene sc;
  sc.recursion_level = tk.integer("recursion_level", 0, 1000000);
  sc.pixels = tk.integer("pixels", 1, 16384);
  unsigned n = tk.integer("n_objects", 0, 50000000);
  unsigned n_tri = 0, n_mesh = 0;
  for (unsigned i = 0; i < n; i++) {
    std::string kind = lower(tk.next("object " + std::to_string(i + 1)));
    std::string field;
    if (kind == "triangle") {
      field = "triangle " + std::to_string(++n_tri);
      for (int k = 0; k < 3; k++) {
        V3 p = read_v3(tk, field + ": vertex " + std::to_string(k + 1));
        sc.loose.v.insert(sc.loose.v.end(), {float(p.x), float(p.y), float(p.z)});
      }
      unsigned base = unsigned(sc.loose.v.size() / 3) - 3;
      sc.loose.t.insert(sc.loose.t.end(), {base, base + 1, base + 2});
      sc.loose.object.push_back(unsigned(sc.objects.size()));
    } else if (kind == "mesh") {
      field = "mesh " + std::to_string(++n_mesh);
      std::string p = tk.next(field + ": path");
      sc.meshes.push_back({p[0] == '/' ? p : dir + p, unsigned(sc.objects.size())});
    } else if (kind == "sphere" || kind == "general" || kind == "prism") {
      fail(tk.at() + "object " + std::to_string(i + 1) + ": `" + kind +
           "` is not supported by this tracer (only triangle and mesh)");
    } else {
      fail(tk.at() + "object " + std::to_string(i + 1) + ": unknown kind `" + kind + "`");
    }
    Material m;
    m.r = float(tk.nonneg(field + ": r"));
    m.g = float(tk.nonneg(field + ": g"));
    m.b = float(tk.nonneg(field + ": b"));
    m.ka = float(tk.nonneg(field + ": ka"));
    m.kd = float(tk.nonneg(field + ": kd"));
    m.ks = float(tk.nonneg(field + ": ks"));
    m.kr = float(tk.nonneg(field + ": kr"));
    m.shine = float(tk.nonneg(field + ": shine"));
    sc.objects.push_back({m});
  }
  unsigned np = tk.integer("n_point_lights", 0, 50000000);
  for (unsigned i = 0; i < np; i++) {
    std::string field = "point light " + std::to_string(i + 1);
    Light l{};
    l.pos = read_v3(tk, field + ": position");
    l.color = {tk.nonneg(field + ": r"), tk.nonneg(field + ": g"), tk.nonneg(field + ": b")};
    sc.lights.push_back(l);
  }
  // the spotlight block is optional: absent when the file ends or the next token is not a number
  std::string nxt = tk.done() ? "" : tk.peek();
  char* end = nullptr;
  if (nxt.empty() || (strtod(nxt.c_str(), &end), *end != '\0')) {
    fprintf(stderr, "whitted: note: %s has no spotlight block\n", path.c_str());
    return sc;
  }
  unsigned ns = tk.integer("n_spot_lights", 0, 50000000);
  for (unsigned i = 0; i < ns; i++) {
    std::string field = "spot light " + std::to_string(i + 1);
    Light l{};
    l.spot = true;
    l.pos = read_v3(tk, field + ": position");
    l.color = {tk.nonneg(field + ": r"), tk.nonneg(field + ": g"), tk.nonneg(field + ": b")};
    V3 d = read_v3(tk, field + ": direction");
    if (length(d) == 0) fail(tk.at() + field + ": direction: must be non-zero");
    l.axis = normalize(d);
    double cut = tk.number(field + ": cutoff");
    if (cut < 0 || cut > 180) fail(tk.at() + field + ": cutoff: expected 0..=180 degrees");
    l.cos_cut = cut == 90 ? 0.0 : std::cos(cut * M_PI / 180.0);
    sc.lights.push_back(l);
  }
  return sc;
}

// ---------------------------------------------------------------------------------------------------------------
// Wavefront OBJ: `v x y z` and `f` lines (3 or more references `i`, `i/t`, `i//n`, `i/t/n`, 1-based, negative
// counting back from the latest vertex; polygons fanned). Everything else is skipped. The file is read whole and
// parsed in place with std::from_chars (correctly rounded, no locale).

static void load_obj(const std::string& path, Mesh& out) {
  std::vector<char> buf = read_file(path);
  const char* p = buf.data();
  const char* end = p + buf.size();
  // a 1M-triangle torus is ~53 bytes a triangle; reserve by the file size so the vectors do not regrow
  out.v.reserve(buf.size() / 40 + 16);
  out.t.reserve(buf.size() / 18 + 16);
  size_t line = 0;
  std::vector<unsigned> poly;
  auto err = [&](const char* what) { fail(path + ":" + std::to_string(line) + ": " + what); };
  auto blank = [](char c) { return c == ' ' || c == '\t'; };
  while (p < end) {
    line++;
    const char* eol = p;
    while (eol < end && *eol != '\n' && *eol != '\r') eol++;
    while (p < eol && blank(*p)) p++;
    if (p + 1 < eol && p[0] == 'v' && blank(p[1])) {
      p += 2;
      for (int k = 0; k < 3; k++) {
        while (p < eol && blank(*p)) p++;
        if (p < eol && *p == '+') p++;  // from_chars does not take a leading '+'
        float x;
        auto r = std::from_chars(p, eol, x);
        if (r.ec != std::errc() || !std::isfinite(x) || (r.ptr < eol && !blank(*r.ptr)))
          err("v: expected three finite coordinates");
        out.v.push_back(x);
        p = r.ptr;
      }
    } else if (p + 1 < eol && p[0] == 'f' && blank(p[1])) {
      p += 2;
      poly.clear();
      long nv = long(out.v.size() / 3);
      while (true) {
        while (p < eol && blank(*p)) p++;
        if (p >= eol) break;
        long i;
        auto r = std::from_chars(p, eol, i);
        if (r.ec != std::errc()) err("f: expected a vertex index");
        long idx = i > 0 ? i - 1 : nv + i;  // 1-based, or counting back from the latest vertex
        if (i == 0 || idx < 0 || idx >= nv) err("f: vertex index out of range");
        poly.push_back(unsigned(idx));
        p = r.ptr;
        while (p < eol && !blank(*p)) p++;  // `/t`, `//n`, `/t/n`
      }
      if (poly.size() < 3) err("f: expected at least three vertices");
      for (size_t k = 1; k + 1 < poly.size(); k++) out.t.insert(out.t.end(), {poly[0], poly[k], poly[k + 1]});
    }
    p = eol;
    if (p < end && *p == '\r') p++;
    if (p < end && *p == '\n') p++;
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Camera (src/scene/camera.rs): the pixel grid of the assignment, pixel centres, square pixels.

struct Camera {
  V3 eye, top_left, du, dv;
};

static Camera make_camera(V3 eye, V3 target, V3 up, double fov_deg, unsigned w, unsigned h) {
  V3 look = normalize(target - eye);
  V3 right = normalize(cross(look, normalize(up)));
  V3 u = cross(right, look);
  const double H = 500.0, W = H * w / h;
  double d = (H / 2) / std::tan(fov_deg * M_PI / 180.0 / 2);
  double pu = W / w, pv = H / h;
  Camera c;
  c.eye = eye;
  c.top_left = eye + look * d - right * (W / 2) + u * (H / 2) + right * (pu / 2) - u * (pv / 2);
  c.du = right * pu;
  c.dv = u * (-pv);
  return c;
}

// ---------------------------------------------------------------------------------------------------------------
// Rendering. A block is 16 lanes in structure-of-arrays form; the per-lane loops have fixed trip counts and no
// early exits (masks select instead), so the compiler vectorizes the shading as Embree vectorizes the traversal.

static const Material FLOOR_MATERIAL = {1, 1, 1, 0.4f, 0.2f, 0.2f, 0.2f, 1};
static const float FLOOR_HALF = 500.0f, TILE = 20.0f;

struct Counts {
  uint64_t primary = 0, shadow = 0, reflection = 0;
};

// One level of a block's mirror chain: each lane's local colour, the weight of the next level's colour, and
// whether the lane hit anything at this level (-1) or not (0).
struct Level {
  float c[3][16];
  float kr[16];
  int hit[16];
};

// Whether the ray meets the floor square at a distance t in (0, tmax); t is set either way.
static inline bool floor_hit(float ox, float oy, float oz, float dx, float dy, float dz, float tmax, float& t) {
  t = -oz / dz;  // +-inf or NaN when dz = 0: then the tests below fail
  float x = ox + t * dx, y = oy + t * dy;
  return (t > 0) & (t < tmax) & (std::fabs(x) <= FLOOR_HALF) & (std::fabs(y) <= FLOOR_HALF);
}

// x[k]^e[k] for x >= 0 and whole e below 2^bits, by squaring, 16 lanes: x^0 = 1, 0^e = 0 for e > 0 (octaray's
// rule).
static inline void power_whole(const float* x, const float* e, unsigned bits, float* out) {
  float acc[16], sq[16], rest[16];
  for (int k = 0; k < 16; k++) acc[k] = 1, sq[k] = x[k], rest[k] = e[k];
  for (unsigned b = 0; b < bits; b++) {
    for (int k = 0; k < 16; k++) {
      if (b > 0) sq[k] *= sq[k];
      float half = std::floor(rest[k] * 0.5f);
      acc[k] = (rest[k] > half + half) ? acc[k] * sq[k] : acc[k];
      rest[k] = half;
    }
  }
  for (int k = 0; k < 16; k++) out[k] = acc[k];
}

class Renderer {
 public:
  Renderer(RTCScene scene, const Scene& sc, std::vector<int> geom_object, bool floor_last)
      : scene_(scene), sc_(sc), geom_object_(std::move(geom_object)), floor_last_(floor_last) {
    rtcInitIntersectContext(&coherent_);
    coherent_.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    rtcInitIntersectContext(&incoherent_);
    // every shininess (the floor's 1 too) a whole number below 256: powers by squaring, else powf
    float top = 1;
    whole_shine_ = true;
    for (const Object& o : sc.objects) {
      whole_shine_ = whole_shine_ && o.m.shine == std::floor(o.m.shine) && o.m.shine < 256;
      top = std::max(top, o.m.shine);
    }
    shine_bits_ = whole_shine_ ? unsigned(std::floor(std::log2(top))) + 1 : 0;
  }

  // Renders the 4 x 4 block at (bx, by) into rgb (width x height x 3 bytes, top row first).
  void block(const Camera& cam, unsigned bx, unsigned by, unsigned w, unsigned h, uint8_t* rgb);

  Counts counts;

 private:
  RTCScene scene_;
  const Scene& sc_;
  std::vector<int> geom_object_;  // Embree geometry ID -> object index (-1: the loose triangles, by primID)
  RTCIntersectContext coherent_, incoherent_;
  bool floor_last_;  // closest hits: the floor tested after Embree's traversal instead of bounding it
  bool whole_shine_;
  unsigned shine_bits_;
  std::vector<Level> chain_;
};

void Renderer::block(const Camera& cam, unsigned bx, unsigned by, unsigned w, unsigned h, uint8_t* rgb) {
  alignas(64) RTCRayHit16 rh;
  alignas(64) RTCRay16 sr;
  alignas(64) int valid[16], svalid[16];
  // the camera rays in double: their floor hits are recomputed from them (exact tiles at tile lines)
  double cdx[16], cdy[16], cdz[16];
  const float ex = float(cam.eye.x), ey = float(cam.eye.y), ez = float(cam.eye.z);
  // (bitwise & and | on the lane conditions below: no branches, so the loops vectorize)
  unsigned n_primary = 0;
  for (int k = 0; k < 16; k++) {
    unsigned i = bx + k % 4, j = by + k / 4;
    valid[k] = ((i < w) & (j < h)) ? -1 : 0;
    n_primary += valid[k] & 1;
    double x = cam.top_left.x + cam.du.x * i + cam.dv.x * j - cam.eye.x;
    double y = cam.top_left.y + cam.du.y * i + cam.dv.y * j - cam.eye.y;
    double z = cam.top_left.z + cam.du.z * i + cam.dv.z * j - cam.eye.z;
    double inv = 1.0 / std::sqrt(x * x + y * y + z * z);
    cdx[k] = x * inv, cdy[k] = y * inv, cdz[k] = z * inv;
    rh.ray.org_x[k] = ex, rh.ray.org_y[k] = ey, rh.ray.org_z[k] = ez;
    rh.ray.dir_x[k] = float(cdx[k]), rh.ray.dir_y[k] = float(cdy[k]), rh.ray.dir_z[k] = float(cdz[k]);
  }
  counts.primary += n_primary;
  const unsigned levels = std::max(1u, sc_.recursion_level);
  unsigned used = 0;
  for (unsigned level = 1;; level++) {
    // closest hit: the floor bounds the ray, then Embree looks for triangles before it (--floor-last: Embree
    // first, then the floor)
    float ft[16];
    for (int k = 0; k < 16; k++) {
      float t;
      bool hit = floor_hit(rh.ray.org_x[k], rh.ray.org_y[k], rh.ray.org_z[k], rh.ray.dir_x[k], rh.ray.dir_y[k],
                           rh.ray.dir_z[k], INFINITY, t);
      ft[k] = hit ? t : INFINITY;
      rh.ray.tnear[k] = 0, rh.ray.tfar[k] = floor_last_ ? INFINITY : ft[k], rh.ray.time[k] = 0;
      rh.ray.mask[k] = 0xFFFFFFFFu, rh.ray.id[k] = k, rh.ray.flags[k] = 0;
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect16(valid, scene_, level == 1 ? &coherent_ : &incoherent_, &rh);
    if (floor_last_) {
      for (int k = 0; k < 16; k++) {
        bool floor_wins = ft[k] < rh.ray.tfar[k];  // a tie goes to the triangle
        rh.hit.geomID[k] = floor_wins ? RTC_INVALID_GEOMETRY_ID : rh.hit.geomID[k];
        rh.ray.tfar[k] = floor_wins ? ft[k] : rh.ray.tfar[k];
      }
    }

    if (chain_.size() < level) chain_.resize(level);
    Level& L = chain_[level - 1];
    used = level;
    // what each lane hit: its material, colour and geometric normal (lane by lane: table look-ups)
    float cr[16], cg[16], cb[16], ka[16], kd[16], ks[16], shine[16], gx[16], gy[16], gz[16];
    int any = 0;
    for (int k = 0; k < 16; k++) {
      unsigned g = rh.hit.geomID[k];
      bool tri = valid[k] && g != RTC_INVALID_GEOMETRY_ID;
      bool flo = valid[k] && !tri && ft[k] < INFINITY;
      L.hit[k] = (tri || flo) ? -1 : 0;
      any |= L.hit[k];
      const Material* m = &FLOOR_MATERIAL;
      float tile = 1;
      if (tri) {
        int o = geom_object_[g];
        m = &sc_.objects[o >= 0 ? o : int(sc_.loose.object[rh.hit.primID[k]])].m;
        gx[k] = rh.hit.Ng_x[k], gy[k] = rh.hit.Ng_y[k], gz[k] = rh.hit.Ng_z[k];
      } else {
        gx[k] = 0, gy[k] = 0, gz[k] = 1;
        if (flo) {
          // the tile: from the double camera ray at level 1, else from the f32 hit point
          double x = rh.ray.org_x[k] + ft[k] * rh.ray.dir_x[k], y = rh.ray.org_y[k] + ft[k] * rh.ray.dir_y[k];
          if (level == 1) {
            double tc = -cam.eye.z / cdz[k];
            x = cam.eye.x + tc * cdx[k], y = cam.eye.y + tc * cdy[k];
          }
          long ti = long(std::floor((x + FLOOR_HALF) / TILE)), tj = long(std::floor((y + FLOOR_HALF) / TILE));
          tile = ((ti + tj) % 2 == 0) ? 1.0f : 0.0f;
        }
      }
      cr[k] = m->r * tile, cg[k] = m->g * tile, cb[k] = m->b * tile;
      ka[k] = m->ka, kd[k] = m->kd, ks[k] = m->ks, L.kr[k] = m->kr, shine[k] = m->shine;
    }
    if (!any) break;

    // the hit point, the unit normal facing the ray, the ambient term, and the origin of this level's secondary
    // rays: off the surface by eps on the side the ray came from
    float px[16], py[16], pz[16], nx[16], ny[16], nz[16], sx[16], sy[16], sz[16];
    for (int k = 0; k < 16; k++) {
      float t = rh.ray.tfar[k], dx = rh.ray.dir_x[k], dy = rh.ray.dir_y[k], dz = rh.ray.dir_z[k];
      px[k] = rh.ray.org_x[k] + t * dx, py[k] = rh.ray.org_y[k] + t * dy, pz[k] = rh.ray.org_z[k] + t * dz;
      float inv = 1.0f / std::sqrt(gx[k] * gx[k] + gy[k] * gy[k] + gz[k] * gz[k]);
      float s = (gx[k] * dx + gy[k] * dy + gz[k] * dz) > 0 ? -inv : inv;
      nx[k] = gx[k] * s, ny[k] = gy[k] * s, nz[k] = gz[k] * s;
      float eps = 1e-4f * std::max(std::max(1.0f, std::fabs(px[k])), std::max(std::fabs(py[k]), std::fabs(pz[k])));
      sx[k] = px[k] + eps * nx[k], sy[k] = py[k] + eps * ny[k], sz[k] = pz[k] + eps * nz[k];
      L.c[0][k] = cr[k] * ka[k], L.c[1][k] = cg[k] * ka[k], L.c[2][k] = cb[k] * ka[k];
    }

    // each light: the lanes it can reach (inside its cone, in front of the surface) get a shadow ray; the floor
    // is tested here, the triangles by Embree; unblocked lanes add the diffuse and specular terms
    for (const Light& lt : sc_.lights) {
      const float lpx = float(lt.pos.x), lpy = float(lt.pos.y), lpz = float(lt.pos.z);
      const float ax = float(lt.axis.x), ay = float(lt.axis.y), az = float(lt.axis.z), cc = float(lt.cos_cut);
      float lx[16], ly[16], lz[16], ndl[16];
      int need = 0;
      unsigned n_shadow = 0;
      for (int k = 0; k < 16; k++) {
        float wx = px[k] - lpx, wy = py[k] - lpy, wz = pz[k] - lpz;
        float dist = std::sqrt(wx * wx + wy * wy + wz * wz);
        bool in_cone = !lt.spot | (ax * wx + ay * wy + az * wz >= cc * dist);
        float inv = 1.0f / dist;
        lx[k] = -wx * inv, ly[k] = -wy * inv, lz[k] = -wz * inv;
        ndl[k] = nx[k] * lx[k] + ny[k] * ly[k] + nz[k] * lz[k];
        bool reach = (L.hit[k] != 0) & (dist > 0) & in_cone & (ndl[k] > 0);
        n_shadow += reach;
        float ox = sx[k], oy = sy[k], oz = sz[k];
        float vx = lpx - ox, vy = lpy - oy, vz = lpz - oz;
        float seg = std::sqrt(vx * vx + vy * vy + vz * vz);
        float is = 1.0f / seg;
        vx *= is, vy *= is, vz *= is;
        float t;
        bool floor_blocks = floor_hit(ox, oy, oz, vx, vy, vz, seg, t);
        sr.org_x[k] = ox, sr.org_y[k] = oy, sr.org_z[k] = oz;
        sr.dir_x[k] = vx, sr.dir_y[k] = vy, sr.dir_z[k] = vz;
        sr.tnear[k] = 0, sr.tfar[k] = seg, sr.time[k] = 0;
        sr.mask[k] = 0xFFFFFFFFu, sr.id[k] = k, sr.flags[k] = 0;
        svalid[k] = (reach & !floor_blocks) ? -1 : 0;
        need |= svalid[k];
      }
      counts.shadow += n_shadow;
      if (!need) continue;
      rtcOccluded16(svalid, scene_, level == 1 ? &coherent_ : &incoherent_, &sr);
      const float lr = float(lt.color.x), lg = float(lt.color.y), lb = float(lt.color.z);
      float rv[16], spec[16];
      for (int k = 0; k < 16; k++) {
        // R = 2 (N.L) N - L against V = -d
        float rx = 2 * ndl[k] * nx[k] - lx[k], ry = 2 * ndl[k] * ny[k] - ly[k], rz = 2 * ndl[k] * nz[k] - lz[k];
        rv[k] = std::max(0.0f, -(rx * rh.ray.dir_x[k] + ry * rh.ray.dir_y[k] + rz * rh.ray.dir_z[k]));
      }
      if (whole_shine_) {
        power_whole(rv, shine, shine_bits_, spec);
      } else {
        for (int k = 0; k < 16; k++) spec[k] = shine[k] == 0 ? 1.0f : (rv[k] > 0 ? std::pow(rv[k], shine[k]) : 0.0f);
      }
      for (int k = 0; k < 16; k++) {
        bool lit = (svalid[k] != 0) & (sr.tfar[k] >= 0);  // Embree sets tfar to -inf on a blocked ray
        float wgt = lit ? kd[k] * ndl[k] + ks[k] * spec[k] : 0.0f;
        L.c[0][k] += lr * cr[k] * wgt, L.c[1][k] += lg * cg[k] * wgt, L.c[2][k] += lb * cb[k] * wgt;
      }
    }

    // the mirror rays of the next level, from lanes that hit something reflective
    if (level >= levels) break;
    int more = 0;
    unsigned n_reflection = 0;
    for (int k = 0; k < 16; k++) {
      float dx = rh.ray.dir_x[k], dy = rh.ray.dir_y[k], dz = rh.ray.dir_z[k];
      float dn = 2 * (dx * nx[k] + dy * ny[k] + dz * nz[k]);
      float rx = dx - dn * nx[k], ry = dy - dn * ny[k], rz = dz - dn * nz[k];
      float il = 1.0f / std::sqrt(rx * rx + ry * ry + rz * rz);
      rh.ray.org_x[k] = sx[k], rh.ray.org_y[k] = sy[k], rh.ray.org_z[k] = sz[k];
      rh.ray.dir_x[k] = rx * il, rh.ray.dir_y[k] = ry * il, rh.ray.dir_z[k] = rz * il;
      valid[k] = ((L.hit[k] != 0) & (L.kr[k] != 0)) ? -1 : 0;
      n_reflection += valid[k] & 1;
      more |= valid[k];
    }
    counts.reflection += n_reflection;
    if (!more) break;
  }

  // fold the chain back from the deepest level, clamping every level to [0, 1]; a lane that missed is black
  float c[3][16] = {};
  for (unsigned l = used; l-- > 0;) {
    const Level& L = chain_[l];
    for (int ch = 0; ch < 3; ch++)
      for (int k = 0; k < 16; k++)
        c[ch][k] = L.hit[k] ? std::min(1.0f, std::max(0.0f, L.c[ch][k] + L.kr[k] * c[ch][k])) : 0.0f;
  }
  for (int k = 0; k < 16; k++) {
    unsigned i = bx + k % 4, j = by + k / 4;
    if (i >= w || j >= h) continue;
    uint8_t* px = rgb + (size_t(j) * w + i) * 3;
    for (int ch = 0; ch < 3; ch++) px[ch] = uint8_t(255.0f * c[ch][k] + 0.5f);  // round(255 c), c in [0, 1]
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Output: 24-bit BMP, bottom row first, written to a temporary file and renamed.

static void write_bmp(const std::string& path, const std::vector<uint8_t>& rgb, unsigned w, unsigned h) {
  unsigned row = (w * 3 + 3) & ~3u;
  uint32_t size = 54 + row * h;
  uint8_t hd[54] = {'B', 'M'};
  auto put32 = [&](int at, uint32_t v) { memcpy(hd + at, &v, 4); };
  put32(2, size);
  put32(10, 54);
  put32(14, 40);
  put32(18, w);
  put32(22, h);
  hd[26] = 1;
  hd[28] = 24;
  put32(34, row * h);
  put32(38, 2835);
  put32(42, 2835);
  std::vector<uint8_t> out(size);
  memcpy(out.data(), hd, 54);
  for (unsigned j = 0; j < h; j++) {
    uint8_t* dst = out.data() + 54 + size_t(h - 1 - j) * row;
    const uint8_t* src = rgb.data() + size_t(j) * w * 3;
    for (unsigned i = 0; i < w; i++) dst[3 * i] = src[3 * i + 2], dst[3 * i + 1] = src[3 * i + 1], dst[3 * i + 2] = src[3 * i];
  }
  std::string tmp = path + ".tmp";
  FILE* f = fopen(tmp.c_str(), "wb");
  if (!f || fwrite(out.data(), 1, out.size(), f) != out.size() || fclose(f) != 0)
    fail(tmp + ": cannot write: " + strerror(errno));
  if (rename(tmp.c_str(), path.c_str()) != 0) fail(path + ": cannot rename: " + strerror(errno));
}

// ---------------------------------------------------------------------------------------------------------------
// Command line

static V3 parse_v3_arg(const char* flag, const char* s) {
  double v[3];
  const char* p = s;
  for (int k = 0; k < 3; k++) {
    char* end;
    v[k] = strtod(p, &end);
    if (end == p || !std::isfinite(v[k]) || (k < 2 ? *end != ',' : *end != '\0'))
      fail(std::string(flag) + ": expected X,Y,Z, got `" + s + "`");
    p = end + 1;
  }
  return {v[0], v[1], v[2]};
}

int main(int argc, char** argv) {
  const char* usage =
      "usage: whitted SCENE -o OUT.bmp [--eye X,Y,Z] [--look-at X,Y,Z] [--up X,Y,Z] [--fov DEG] [--size N|WxH] "
      "[--threads 1] [--floor-last]";
  std::string scene_path, out_path;
  double s = M_SQRT1_2;
  V3 eye{100, 100, 50}, up{0, 0, 1};
  V3 target = eye + V3{-s, -s, 0};
  double fov = 80;
  unsigned w = 0, h = 0;
  bool floor_last = false;
  for (int a = 1; a < argc; a++) {
    std::string f = argv[a];
    auto val = [&]() -> const char* {
      if (a + 1 >= argc) fail(f + ": expected a value\n" + usage);
      return argv[++a];
    };
    if (f == "-o") out_path = val();
    else if (f == "--eye") eye = parse_v3_arg("--eye", val());
    else if (f == "--look-at") target = parse_v3_arg("--look-at", val());
    else if (f == "--up") up = parse_v3_arg("--up", val());
    else if (f == "--fov") {
      const char* v = val();
      char* end;
      fov = strtod(v, &end);
      if (*end || !(fov > 0 && fov < 180)) fail(std::string("--fov: expected degrees in (0, 180), got `") + v + "`");
    } else if (f == "--size") {
      const char* v = val();
      if (sscanf(v, "%ux%u", &w, &h) != 2) {
        char* end;
        w = h = unsigned(strtoul(v, &end, 10));
        if (*end) w = 0;
      }
      if (w < 1 || h < 1 || w > 16384 || h > 16384) fail(std::string("--size: expected N or WxH (1..16384), got `") + v + "`");
    } else if (f == "--threads") {
      if (std::string(val()) != "1") fail("--threads: this tracer renders on 1 thread only");
    } else if (f == "--floor-last") floor_last = true;
    else if (f[0] == '-') fail("unknown option `" + f + "`\n" + usage);
    else if (scene_path.empty()) scene_path = f;
    else fail(std::string("one scene only\n") + usage);
  }
  if (scene_path.empty() || out_path.empty()) fail(usage);
  V3 look = target - eye;
  if (length(look) == 0 || length(up) == 0 || length(cross(normalize(look), normalize(up))) < 1e-12)
    fail("--eye, --look-at, --up: the view direction must be non-zero and not parallel to up");

  // denormals flushed, as Embree's own tutorials do
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);

  auto t0 = clk::now();
  Scene sc = parse_scene(scene_path);
  std::vector<Mesh> meshes(sc.meshes.size());
  for (size_t i = 0; i < sc.meshes.size(); i++) load_obj(sc.meshes[i].first, meshes[i]);
  if (w == 0) w = h = sc.pixels;
  auto t1 = clk::now();

  RTCDevice dev = rtcNewDevice("threads=1");
  if (!dev) fail("rtcNewDevice failed");
  RTCScene scene = rtcNewScene(dev);  // static scene, RTC_BUILD_QUALITY_MEDIUM (the defaults)
  std::vector<int> geom_object;
  size_t n_tris = 0;
  auto attach = [&](Mesh& m, int object) {
    size_t nv = m.v.size() / 3, nt = m.t.size() / 3;
    if (nt == 0) return;
    m.v.push_back(0);  // Embree reads vertices 16 bytes at a time
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m.v.data(), 0, 12, nv);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m.t.data(), 0, 12, nt);
    rtcCommitGeometry(g);
    unsigned id = rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    if (geom_object.size() <= id) geom_object.resize(id + 1, -1);
    geom_object[id] = object;
    n_tris += nt;
  };
  for (size_t i = 0; i < meshes.size(); i++) attach(meshes[i], int(sc.meshes[i].second));
  attach(sc.loose, -1);
  rtcCommitScene(scene);
  if (rtcGetDeviceError(dev) != RTC_ERROR_NONE) fail("Embree could not build the scene");
  auto t2 = clk::now();

  Camera cam = make_camera(eye, target, up, fov, w, h);
  Renderer r(scene, sc, geom_object, floor_last);
  std::vector<uint8_t> rgb(size_t(w) * h * 3);
  for (unsigned by = 0; by < h; by += 4)
    for (unsigned bx = 0; bx < w; bx += 4) r.block(cam, bx, by, w, h, rgb.data());
  auto t3 = clk::now();
  write_bmp(out_path, rgb, w, h);
  auto t4 = clk::now();

  const Counts& c = r.counts;
  uint64_t rays = c.primary + c.shadow + c.reflection;
  double work = secs(t0, t3);
  fprintf(stderr,
          "whitted: %ux%u, %zu triangles: %.3f s (load %.3f s, build %.3f s, render %.3f s; write %.3f s), %.2f M rays "
          "(%llu primary, %llu shadow, %llu reflection), %.2f Mrays/s (render)\n",
          w, h, n_tris, work, secs(t0, t1), secs(t1, t2), secs(t2, t3), secs(t3, t4), rays / 1e6,
          (unsigned long long)c.primary, (unsigned long long)c.shadow, (unsigned long long)c.reflection,
          rays / 1e6 / std::max(secs(t2, t3), 1e-9));
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return 0;
}
