/* Host test of the generated C codec (firmware_stub/generated/hil_protocol.c).
 * Checks every golden frame (golden_frames.h, generated from tests/golden/frames.json),
 * pack/unpack round trips of pseudo-random raw values, and size checks.
 * Exit status: number of failures (0 = pass). C99, no malloc. */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "hil_protocol.h"
#include "golden_frames.h"

#define ROUND_TRIPS 1000

static uint32_t lcg_state = 12345u;

static uint32_t lcg_next(void)
{
    lcg_state = lcg_state * 1664525u + 1013904223u;
    return lcg_state;
}

/* 0 when ok, else 1 after printing the failure (a printf format and its values). */
static int fail_unless(int ok, const char *fmt, ...)
{
    va_list ap;
    if (ok) {
        return 0;
    }
    va_start(ap, fmt);
    (void)vprintf(fmt, ap);
    va_end(ap);
    (void)putchar('\n');
    return 1;
}

/* Pack and unpack of pseudo-random raw values, round trip k. */
static int cmd_fd_round_trip(int k)
{
    struct hil_protocol_cmd_fd_t in;
    struct hil_protocol_cmd_fd_t back;
    uint8_t buf[HIL_PROTOCOL_CMD_FD_LENGTH];
    memset(&in, 0, sizeof in);
    in.seq = (uint16_t)lcg_next();
    in.state0 = (uint8_t)(lcg_next() & 63u);
    in.state1 = (uint8_t)(lcg_next() & 63u);
    in.state2 = (uint8_t)(lcg_next() & 63u);
    in.n_states = (uint8_t)(1u + lcg_next() % 3u);
    in.duration0 = lcg_next() & 0xFFFFFu;
    in.duration1 = lcg_next() & 0xFFFFFu;
    in.duration2 = lcg_next() & 0xFFFFFu;
    in.vector_id = (uint8_t)lcg_next();
    in.candidates = (uint8_t)lcg_next();
    in.exec_time_ns = lcg_next();
    in.status = (uint8_t)lcg_next();
    in.mirror = (uint8_t)(lcg_next() & 1u);
    return fail_unless(hil_protocol_cmd_fd_pack(buf, &in, sizeof buf) == (int)sizeof buf
                       && hil_protocol_cmd_fd_unpack(&back, buf, sizeof buf) == 0
                       && back.seq == in.seq && back.state0 == in.state0 && back.state1 == in.state1
                       && back.state2 == in.state2 && back.n_states == in.n_states
                       && back.duration0 == in.duration0 && back.duration1 == in.duration1
                       && back.duration2 == in.duration2 && back.vector_id == in.vector_id
                       && back.candidates == in.candidates && back.exec_time_ns == in.exec_time_ns
                       && back.status == in.status && back.mirror == in.mirror,
                       "cmd_fd round trip %d failed", k);
}

static int meas_split_round_trip(int k)
{
    struct hil_protocol_meas_a_t a;
    struct hil_protocol_meas_a_t a2;
    struct hil_protocol_meas_b_t b;
    struct hil_protocol_meas_b_t b2;
    uint8_t buf[8];
    a.seq = (uint16_t)lcg_next();
    a.i_a = (int16_t)lcg_next();
    a.i_b = (int16_t)lcg_next();
    a.i_c = (int16_t)lcg_next();
    b.seq_lo = (uint8_t)a.seq;
    b.theta_e = (uint16_t)lcg_next();
    b.omega_m = (int16_t)lcg_next();
    b.vdc = (uint16_t)lcg_next();
    b.status = (uint8_t)lcg_next();
    return fail_unless(hil_protocol_meas_a_pack(buf, &a, sizeof buf) == 8
                       && hil_protocol_meas_a_unpack(&a2, buf, 8) == 0 && memcmp(&a, &a2, sizeof a) == 0,
                       "meas_a round trip %d failed", k)
           + fail_unless(hil_protocol_meas_b_pack(buf, &b, sizeof buf) == 8
                         && hil_protocol_meas_b_unpack(&b2, buf, 8) == 0
                         && b2.seq_lo == b.seq_lo && b2.theta_e == b.theta_e && b2.omega_m == b.omega_m
                         && b2.vdc == b.vdc && b2.status == b.status,
                         "meas_b round trip %d failed", k);
}

static int check_sizes(void)
{
    int fails = 0;
    uint8_t small[4] = {0};
    struct hil_protocol_meas_a_t a;
    struct hil_protocol_cmd_fd_t c;
    memset(&a, 0, sizeof a);
    memset(&c, 0, sizeof c);
    fails += fail_unless(hil_protocol_meas_a_pack(small, &a, sizeof small) < 0,
                         "meas_a pack into 4 bytes did not fail");
    fails += fail_unless(hil_protocol_cmd_fd_unpack(&c, small, sizeof small) < 0,
                         "cmd_fd unpack of 4 bytes did not fail");
    fails += fail_unless(HIL_PROTOCOL_MEAS_FD_LENGTH == 16u && HIL_PROTOCOL_CMD_FD_LENGTH == 20u
                         && HIL_PROTOCOL_CMD_C_LENGTH == 8u, "unexpected frame lengths");
    return fails;
}

/* Encoders never cast NaN or an out-of-type value to an integer (undefined in C): NaN gives 0, the rest saturates
 * to the signal's raw range (src/pmsm_hil/protocol/gen_c.py). */
static int check_encode_saturates(void)
{
    int fails = 0;
#define EXPECT(got, want)                                                                                     \
    (fails += fail_unless((long long)(got) == (long long)(want), "%s = %lld, want %lld", #got, (long long)(got), \
                          (long long)(want)))
    EXPECT(hil_protocol_meas_a_i_a_encode(NAN), 0);
    EXPECT(hil_protocol_meas_a_i_a_encode(INFINITY), 32767);
    EXPECT(hil_protocol_meas_a_i_a_encode(-1.0e30f), -32768);
    EXPECT(hil_protocol_meas_b_vdc_encode(NAN), 0);
    EXPECT(hil_protocol_meas_b_vdc_encode(-5.0f), 0);
    EXPECT(hil_protocol_meas_b_vdc_encode(1.0e9f), 65535);
    EXPECT(hil_protocol_cmd_a_duration0_encode(2.0e6f), 1048575);
    EXPECT(hil_protocol_cmd_a_duration0_encode(-INFINITY), 0);
    EXPECT(hil_protocol_cmd_c_exec_time_ns_encode(1.0e20f), 4294967295u);
    EXPECT(hil_protocol_cmd_c_exec_time_ns_encode(NAN), 0);
    EXPECT(hil_protocol_cmd_a_n_states_encode(NAN), 0);
    EXPECT(hil_protocol_config_param_param_id_encode(300.0f), 255);
#undef EXPECT
    return fails;
}

int main(void)
{
    int fails = 0;
    int i;
    for (i = 0; i < GOLDEN_CHECK_COUNT; i++) {
        int f = golden_checks[i].fn();
        if (f != 0) {
            printf("FAIL golden %s (%d)\n", golden_checks[i].name, f);
        }
        fails += f;
    }
    for (i = 0; i < ROUND_TRIPS; i++) {
        fails += cmd_fd_round_trip(i);
    }
    for (i = 0; i < ROUND_TRIPS; i++) {
        fails += meas_split_round_trip(i);
    }
    fails += check_sizes();
    fails += check_encode_saturates();
    printf("test_codec: %d golden frames, %d failure(s)\n", GOLDEN_CHECK_COUNT, fails);
    return fails != 0;
}
