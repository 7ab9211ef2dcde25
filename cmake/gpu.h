// Installed as <layertrace/gpu.h>: layertrace on the GPU, in your OpenGL context (api/gpu.h).
#pragma once
#include "layertrace/api/gpu.h"
