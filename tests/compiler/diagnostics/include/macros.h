#pragma once
#define SQ(x) ((x) * (x))
#define AMOUNT 0.25
