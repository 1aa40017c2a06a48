// Sobol direction numbers of the first SOBOL_DIMENSIONS dimensions, 32 per
// dimension: entry 32 d + k (k = 0..31) is v_{k+1} = m_{k+1} << (31 - k), the
// column that bit k of the sample index adds (xor) to the 32-bit fraction of
// dimension d. Computed once (a short Python script, the same recurrence as
// src/render/sobol.rs) from each dimension's primitive polynomial over GF(2)
// and initial numbers m_1..m_s as Joe and Kuo list them ("Constructing Sobol
// sequences with better two-dimensional projections", 2008), by their
// recurrence m_k = 2 a_1 m_{k-1} ^ 4 a_2 m_{k-2} ^ ... ^ 2^s m_{k-s} ^ m_{k-s}.
// The unit test render::sobol::tests::glsl_table_matches_the_polynomials
// recomputes them and checks this file; it prints the table if they differ.
#ifndef SOBOL_GLSL
#define SOBOL_GLSL

const uint SOBOL_DIRECTIONS[SOBOL_DIMENSIONS * 32] = uint[](
    // dimension 0: van der Corput (every m_k = 1)
    0x80000000u, 0x40000000u, 0x20000000u, 0x10000000u, 0x08000000u, 0x04000000u, 0x02000000u, 0x01000000u,
    0x00800000u, 0x00400000u, 0x00200000u, 0x00100000u, 0x00080000u, 0x00040000u, 0x00020000u, 0x00010000u,
    0x00008000u, 0x00004000u, 0x00002000u, 0x00001000u, 0x00000800u, 0x00000400u, 0x00000200u, 0x00000100u,
    0x00000080u, 0x00000040u, 0x00000020u, 0x00000010u, 0x00000008u, 0x00000004u, 0x00000002u, 0x00000001u,
    // dimension 1: x + 1 (degree 1, a = 0, m_1 = 1)
    0x80000000u, 0xC0000000u, 0xA0000000u, 0xF0000000u, 0x88000000u, 0xCC000000u, 0xAA000000u, 0xFF000000u,
    0x80800000u, 0xC0C00000u, 0xA0A00000u, 0xF0F00000u, 0x88880000u, 0xCCCC0000u, 0xAAAA0000u, 0xFFFF0000u,
    0x80008000u, 0xC000C000u, 0xA000A000u, 0xF000F000u, 0x88008800u, 0xCC00CC00u, 0xAA00AA00u, 0xFF00FF00u,
    0x80808080u, 0xC0C0C0C0u, 0xA0A0A0A0u, 0xF0F0F0F0u, 0x88888888u, 0xCCCCCCCCu, 0xAAAAAAAAu, 0xFFFFFFFFu
);

#endif
