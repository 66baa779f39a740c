// What a fresh page costs: maps SIZE_MB of anonymous memory, asks for 2 MiB pages or
// forbids them, and times the first write to every 4 KiB (the kernel's fault and clear),
// then a memset of the same, now mapped, memory (the write bandwidth).
// usage: gcc -O2 benches/page_touch.c -o /tmp/page_touch && /tmp/page_touch SIZE_MB HUGE(0|1)
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s SIZE_MB HUGE(0|1)\n", argv[0]);
    return 2;
  }
  size_t n = (size_t)atoi(argv[1]) << 20, huge = 2u << 20;
  int want_huge = atoi(argv[2]);
  char *p = mmap(0, n + huge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) {
    perror("mmap");
    return 1;
  }
  char *q = (char *)(((size_t)p + huge - 1) & ~(huge - 1));
  madvise(q, n, want_huge ? MADV_HUGEPAGE : MADV_NOHUGEPAGE);
  double t0 = now();
  for (size_t i = 0; i < n; i += 4096) q[i] = 1;
  double t1 = now();
  memset(q, 2, n);
  double t2 = now();
  printf("%zu MB, 2 MiB pages %s: first touch %.1f ms (%.2f GB/s), memset after %.1f ms\n", n >> 20,
         want_huge ? "asked" : "off", (t1 - t0) * 1e3, n / (t1 - t0) / 1e9, (t2 - t1) * 1e3);
  return 0;
}
