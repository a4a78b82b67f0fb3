// Includes broken_helper.h, so its error has a two-level include stack; the two errors here share
// one one-level stack.
#include "broken_helper.h"
float twice(float a) { return a * Kq + Kr; }
