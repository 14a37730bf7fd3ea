/* Native Embree 3 side of `hort bench kernel`: reads the rays HORT traced (written by
 * local-emulator/src/bench/kernel.rs), traces the identical rays with Embree in one thread and
 * prints one JSON object with timings and agreement counts.
 *
 * Input (little-endian): "HORTKRN1", u32 triangles, u32 primary, u32 shadow, u32 reserved,
 *   f32 corners[9 * triangles] (scene order),
 *   f32 primary rays[6 * primary] (origin, dir), then HORT's answers: u32 id (~0 = miss), f32 t,
 *   f32 shadow rays[7 * shadow] (origin, dir, t_max), then HORT's answers: u8 occluded.
 * Output: build, rtcIntersect1, rtcIntersect16 (incoherent and coherent context) and rtcOccluded1
 *   seconds, and agreement counts.
 * Usage: embree_harness FILE REPEATS  (timings are the best of REPEATS passes)
 * Build: cc -O2 embree_harness.c -o embree_harness -lembree3
 */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void *read_exact(FILE *f, size_t bytes) {
  void *p = malloc(bytes ? bytes : 1);
  if (!p || fread(p, 1, bytes, f) != bytes) {
    fprintf(stderr, "embree_harness: short input\n");
    exit(2);
  }
  return p;
}

/* The best of `repeats` passes of rtcIntersect16 over the `np` primary rays, 16 consecutive
 * rays a packet, in the context `ctx`. */
static double packets16(RTCScene scene, struct RTCIntersectContext *ctx, const float *prim,
                        uint32_t np, int repeats) {
  double best = 1e30;
  for (int r = 0; r < repeats; r++) {
    double s = now();
    for (uint32_t base = 0; base < np; base += 16) {
      struct RTCRayHit16 rh __attribute__((aligned(64)));
      int valid[16] __attribute__((aligned(64)));
      for (int k = 0; k < 16; k++) {
        uint32_t i = base + k;
        valid[k] = i < np ? -1 : 0;
        const float *q = prim + 6 * (size_t)(i < np ? i : base);
        rh.ray.org_x[k] = q[0]; rh.ray.org_y[k] = q[1]; rh.ray.org_z[k] = q[2];
        rh.ray.dir_x[k] = q[3]; rh.ray.dir_y[k] = q[4]; rh.ray.dir_z[k] = q[5];
        rh.ray.tnear[k] = 0.0f; rh.ray.tfar[k] = INFINITY;
        rh.ray.mask[k] = (unsigned)-1; rh.ray.flags[k] = 0; rh.ray.time[k] = 0.0f;
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect16(valid, scene, ctx, &rh);
    }
    double e = now() - s;
    if (e < best) best = e;
  }
  return best;
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s FILE REPEATS\n", argv[0]);
    return 2;
  }
  int repeats = atoi(argv[2]);
  if (repeats < 1) repeats = 1;
  FILE *f = fopen(argv[1], "rb");
  if (!f) {
    perror(argv[1]);
    return 2;
  }
  char magic[8];
  uint32_t head[4];
  if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "HORTKRN1", 8) != 0 ||
      fread(head, 4, 4, f) != 4) {
    fprintf(stderr, "embree_harness: not a HORT kernel ray file\n");
    return 2;
  }
  uint32_t nt = head[0], np = head[1], ns = head[2];
  float *corners = read_exact(f, (size_t)nt * 36);
  float *prim = read_exact(f, (size_t)np * 24);
  uint32_t *ours_hit = read_exact(f, (size_t)np * 8);
  float *shadow = read_exact(f, (size_t)ns * 28);
  uint8_t *ours_occ = read_exact(f, ns);
  fclose(f);

  RTCDevice device = rtcNewDevice("threads=1");
  if (!device) {
    fprintf(stderr, "embree_harness: rtcNewDevice failed\n");
    return 1;
  }
  RTCScene scene = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                      3 * sizeof(float), (size_t)nt * 3);
  unsigned *ib = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                         3 * sizeof(unsigned), nt);
  memcpy(vb, corners, (size_t)nt * 36);
  for (uint32_t i = 0; i < 3 * nt; i++) ib[i] = i;
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  double t0 = now();
  rtcCommitScene(scene);
  double build = now() - t0;

  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);

  /* Single rays, closest hit. */
  double best1 = 1e30;
  uint64_t same_id = 0, hits = 0;
  for (int r = 0; r < repeats; r++) {
    double s = now();
    uint64_t h = 0, same = 0;
    for (uint32_t i = 0; i < np; i++) {
      const float *q = prim + 6 * (size_t)i;
      struct RTCRayHit rh;
      rh.ray.org_x = q[0]; rh.ray.org_y = q[1]; rh.ray.org_z = q[2];
      rh.ray.dir_x = q[3]; rh.ray.dir_y = q[4]; rh.ray.dir_z = q[5];
      rh.ray.tnear = 0.0f; rh.ray.tfar = INFINITY;
      rh.ray.mask = (unsigned)-1; rh.ray.flags = 0; rh.ray.time = 0.0f;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx, &rh);
      uint32_t id = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? 0xffffffffu : rh.hit.primID;
      h += id != 0xffffffffu;
      same += id == ours_hit[2 * (size_t)i];
    }
    double e = now() - s;
    if (e < best1) best1 = e;
    hits = h;
    same_id = same;
  }

  /* Packets of 16 (consecutive rays: 16 samples of a pixel, or 16 pixels of a row), closest
   * hit; once as incoherent rays (the default context) and once with the coherent flag, as
   * Mitsuba 3 traces its camera rays. */
  double best16 = packets16(scene, &ctx, prim, np, repeats);
  struct RTCIntersectContext coherent;
  rtcInitIntersectContext(&coherent);
  coherent.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  double best16c = packets16(scene, &coherent, prim, np, repeats);

  /* Single shadow rays. */
  double best_s = 1e30;
  uint64_t occluded = 0, same_occ = 0;
  for (int r = 0; r < repeats; r++) {
    double s = now();
    uint64_t o = 0, same = 0;
    for (uint32_t i = 0; i < ns; i++) {
      const float *q = shadow + 7 * (size_t)i;
      struct RTCRay ray;
      ray.org_x = q[0]; ray.org_y = q[1]; ray.org_z = q[2];
      ray.dir_x = q[3]; ray.dir_y = q[4]; ray.dir_z = q[5];
      ray.tnear = 0.0f; ray.tfar = q[6];
      ray.mask = (unsigned)-1; ray.flags = 0; ray.time = 0.0f;
      rtcOccluded1(scene, &ctx, &ray);
      int occ = ray.tfar == -INFINITY;
      o += occ;
      same += occ == (ours_occ[i] != 0);
    }
    double e = now() - s;
    if (e < best_s) best_s = e;
    occluded = o;
    same_occ = same;
  }

  printf("{\"triangles\":%u,\"build_s\":%.6f,\"primary_rays\":%u,\"primary_s\":%.6f,"
         "\"primary16_s\":%.6f,\"primary16_coherent_s\":%.6f,\"primary_hits\":%llu,\"primary_same_id\":%llu,"
         "\"shadow_rays\":%u,\"shadow_s\":%.6f,\"shadow_occluded\":%llu,"
         "\"shadow_same\":%llu}\n",
         nt, build, np, best1, best16, best16c, (unsigned long long)hits,
         (unsigned long long)same_id, ns, best_s, (unsigned long long)occluded,
         (unsigned long long)same_occ);
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  return 0;
}
