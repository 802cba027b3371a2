// Fixture for tests/independence: an "engine" that breaks each include rule once. Never compiled.
#include "core/engine.hpp"
#include "formulations/kane/kane.hpp"
#include "../lagrange/lagrange.hpp"
