// Includes broken_helper.h, so its error has a two-level include stack.
#include "broken_helper.h"
