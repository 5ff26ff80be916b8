/* NDLCom deframing in C: the byte loop of codec.FrameDecoder.feed (docs/protocol.md section 2).
 *
 * Python's per-frame work (split, unescape, FCS, header checks, counters) cost ~2.5 us a frame, about
 * 80 us of every 1 ms control cycle for 32 telemetry frames; here it is ~0.1 us a frame. Only the part
 * between the first and the last flag is handled: the streaming state (sync, pending bytes, oversize
 * pending) stays in FrameDecoder.feed, which is the one caller.
 *
 * split_frames(data, frame_type, frames, crc_errors, malformed, oversize, lost, last_counter, resync)
 *   data:  bytes whose every 0x7E delimits; the text before the first flag has been removed by the caller.
 *   frame_type: codec.Frame (a NamedTuple): each good frame is built as one, (receiver, sender, counter, payload).
 *   frames .. lost: LinkCounters' per-sender lists (256 ints), last_counter its 65536-entry list; updated
 *   in place exactly as FrameDecoder.feed documents.
 *   Returns (list of frames, garbage byte count, offset of the pending part after the last flag).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#define FLAG 0x7E
#define ESCAPE 0x7D
#define ESCAPE_XOR 0x20
#define HEADER_SIZE 4
#define MIN_FRAME_SIZE 6                       /* header + FCS */
#define MAX_FRAME_SIZE (MIN_FRAME_SIZE + 255) /* header + 255 payload bytes + FCS */
#define MAX_ESCAPED_BODY (2 * MAX_FRAME_SIZE)

static uint16_t fcs_table[256];

static void make_fcs_table(void) {
    for (int byte = 0; byte < 256; ++byte) {
        uint16_t crc = (uint16_t)byte;
        for (int bit = 0; bit < 8; ++bit) crc = (crc & 1) ? (uint16_t)((crc >> 1) ^ 0x8408) : (uint16_t)(crc >> 1);
        fcs_table[byte] = crc;
    }
}

/* Add ``delta`` to list[index] (a Python int). Returns -1 with an exception set on failure. */
static int list_add(PyObject *list, Py_ssize_t index, long delta) {
    PyObject *old = PyList_GET_ITEM(list, index);
    long value = PyLong_AsLong(old);
    if (value == -1 && PyErr_Occurred()) return -1;
    PyObject *updated = PyLong_FromLong(value + delta);
    if (updated == NULL) return -1;
    PyList_SET_ITEM(list, index, updated);
    Py_DECREF(old);
    return 0;
}

/* Set list[index] to the int ``value``. Returns -1 with an exception set on failure. */
static int list_set(PyObject *list, Py_ssize_t index, long value) {
    PyObject *updated = PyLong_FromLong(value);
    if (updated == NULL) return -1;
    PyObject *old = PyList_GET_ITEM(list, index);
    PyList_SET_ITEM(list, index, updated);
    Py_DECREF(old);
    return 0;
}

/* Unescape ``size`` bytes into ``out``; returns the unescaped size, or -1 when an escape is not followed by
 * 0x5E or 0x5D (malformed; an escape right before the closing flag is RFC 1662's abort). */
static Py_ssize_t unescape(const uint8_t *in, Py_ssize_t size, uint8_t *out) {
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < size; ++i) {
        uint8_t byte = in[i];
        if (byte == ESCAPE) {
            if (i + 1 >= size || (in[i + 1] != 0x5E && in[i + 1] != 0x5D)) return -1;
            byte = in[++i] ^ ESCAPE_XOR;
        }
        out[n++] = byte;
    }
    return n;
}

/* The sender byte of a damaged candidate, read through the escaping as far as it goes (for attribution). */
static int best_effort_sender(const uint8_t *in, Py_ssize_t size) {
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < size; ++i) {
        uint8_t byte = in[i];
        if (byte == ESCAPE && i + 1 < size && (in[i + 1] == 0x5E || in[i + 1] == 0x5D)) byte = in[++i] ^ ESCAPE_XOR;
        if (n == 1) return byte;
        ++n;
    }
    return 0;
}

static int check_list(PyObject *list, Py_ssize_t size, const char *name) {
    if (!PyList_CheckExact(list) || PyList_GET_SIZE(list) != size) {
        PyErr_Format(PyExc_TypeError, "%s must be a list of %zd ints", name, size);
        return -1;
    }
    return 0;
}

static PyObject *split_frames(PyObject *module, PyObject *args) {
    Py_buffer view;
    PyTypeObject *frame_type;
    PyObject *frames_count, *crc_errors, *malformed, *oversize, *lost, *last_counter;
    int resync;
    (void)module;
    if (!PyArg_ParseTuple(args, "y*O!O!O!O!O!O!O!p", &view, &PyType_Type, &frame_type, &PyList_Type, &frames_count, &PyList_Type, &crc_errors,
                          &PyList_Type, &malformed, &PyList_Type, &oversize, &PyList_Type, &lost, &PyList_Type,
                          &last_counter, &resync))
        return NULL;
    PyObject *frames = NULL;
    if (!PyType_IsSubtype(frame_type, &PyTuple_Type)) {
        PyErr_SetString(PyExc_TypeError, "frame_type must be a tuple subclass (codec.Frame)");
        goto fail;
    }
    if (check_list(frames_count, 256, "frames") || check_list(crc_errors, 256, "crc_errors") ||
        check_list(malformed, 256, "malformed") || check_list(oversize, 256, "oversize") ||
        check_list(lost, 256, "lost") || check_list(last_counter, 65536, "last_counter"))
        goto fail;
    frames = PyList_New(0);
    if (frames == NULL) goto fail;
    const uint8_t *data = (const uint8_t *)view.buf;
    const Py_ssize_t size = view.len;
    uint8_t body[MAX_ESCAPED_BODY];
    long garbage = 0;
    Py_ssize_t start = 0;
    for (;;) {
        const uint8_t *flag = memchr(data + start, FLAG, (size_t)(size - start));
        if (flag == NULL) break; /* the rest is the pending part */
        const Py_ssize_t end = flag - data;
        const uint8_t *part = data + start;
        const Py_ssize_t escaped_size = end - start;
        start = end + 1;
        if (escaped_size < MIN_FRAME_SIZE) { /* an empty part is just two adjacent flags */
            garbage += (long)escaped_size;
            continue;
        }
        if (escaped_size > MAX_ESCAPED_BODY) {
            if (list_add(oversize, best_effort_sender(part, escaped_size < 8 ? escaped_size : 8), 1)) goto fail;
            continue;
        }
        const Py_ssize_t n = unescape(part, escaped_size, body);
        if (n < 0) {
            if (list_add(malformed, best_effort_sender(part, escaped_size), 1)) goto fail;
            continue;
        }
        if (n < MIN_FRAME_SIZE) {
            garbage += (long)escaped_size;
            continue;
        }
        const int receiver = body[0], sender = body[1], counter = body[2], length = body[3];
        uint16_t fcs = 0xFFFF;
        for (Py_ssize_t i = 0; i < n; ++i) fcs = (uint16_t)((fcs >> 8) ^ fcs_table[(fcs ^ body[i]) & 0xFF]);
        if (n > MAX_FRAME_SIZE) {
            if (list_add(oversize, sender, 1)) goto fail;
        } else if (fcs != 0) {
            if (list_add(crc_errors, sender, 1)) goto fail;
        } else if (length != n - MIN_FRAME_SIZE) {
            if (list_add(malformed, sender, 1)) goto fail;
        } else {
            const Py_ssize_t key = (Py_ssize_t)sender << 8 | receiver;
            long previous = PyLong_AsLong(PyList_GET_ITEM(last_counter, key));
            if (previous == -1 && PyErr_Occurred()) goto fail;
            if (previous >= 0 && !resync && list_add(lost, sender, (counter - previous - 1) & 0xFF)) goto fail;
            if (list_set(last_counter, key, counter) || list_add(frames_count, sender, 1)) goto fail;
            PyObject *frame = frame_type->tp_alloc(frame_type, 4);
            if (frame == NULL) goto fail;
            PyObject *fields[4] = {PyLong_FromLong(receiver), PyLong_FromLong(sender), PyLong_FromLong(counter),
                                   PyBytes_FromStringAndSize((const char *)body + HEADER_SIZE, length)};
            for (int i = 0; i < 4; ++i) PyTuple_SET_ITEM(frame, i, fields[i]);
            if (!fields[0] || !fields[1] || !fields[2] || !fields[3]) {
                Py_DECREF(frame);
                goto fail;
            }
            int appended = PyList_Append(frames, frame);
            Py_DECREF(frame);
            if (appended) goto fail;
        }
    }
    PyBuffer_Release(&view);
    return Py_BuildValue("(Nln)", frames, garbage, start);
fail:
    Py_XDECREF(frames);
    PyBuffer_Release(&view);
    return NULL;
}

/* newest_payloads(frames, board_of, size, kind, version): the driver's sorting of one cycle's frames.
 *   frames: Frame tuples (receiver, sender, counter, payload) in arrival order.
 *   board_of: 256 bytes, the board index of each sender address (255: not a board of the map).
 *   Keeps, per board, the payload of its latest frame that has ``size`` bytes starting with ``kind`` and
 *   ``version`` (a later frame supersedes an earlier one).
 *   Returns (boards, payloads, unknown, bad): the board indices (bytes, first-arrival order), their kept payloads
 *   joined in that order, the frames from unknown senders and those with another size, kind or version. */
static PyObject *newest_payloads(PyObject *module, PyObject *args) {
    PyObject *frames;
    Py_buffer board_of;
    Py_ssize_t size;
    int kind, version;
    if (!PyArg_ParseTuple(args, "O!y*nii", &PyList_Type, &frames, &board_of, &size, &kind, &version)) return NULL;
    if (board_of.len != 256 || size <= 0) {
        PyBuffer_Release(&board_of);
        PyErr_SetString(PyExc_ValueError, "board_of must be 256 bytes and size positive");
        return NULL;
    }
    const unsigned char *boards_of = board_of.buf;
    PyObject *latest[255] = {NULL}; /* borrowed from ``frames`` */
    unsigned char order[255];
    int n_boards = 0;
    long unknown = 0, bad = 0;
    Py_ssize_t n = PyList_GET_SIZE(frames);
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *frame = PyList_GET_ITEM(frames, i);
        if (!PyTuple_Check(frame) || PyTuple_GET_SIZE(frame) != 4) {
            PyBuffer_Release(&board_of);
            PyErr_SetString(PyExc_TypeError, "frames: (receiver, sender, counter, payload) tuples expected");
            return NULL;
        }
        long sender = PyLong_AsLong(PyTuple_GET_ITEM(frame, 1));
        PyObject *payload = PyTuple_GET_ITEM(frame, 3);
        if ((sender == -1 && PyErr_Occurred()) || !PyBytes_Check(payload)) {
            PyBuffer_Release(&board_of);
            if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "frames: payloads must be bytes");
            return NULL;
        }
        int board = (sender >= 0 && sender < 256) ? boards_of[sender] : 255;
        if (board == 255) {
            ++unknown;
            continue;
        }
        const unsigned char *data = (const unsigned char *)PyBytes_AS_STRING(payload);
        if (PyBytes_GET_SIZE(payload) != size || data[0] != kind || data[1] != version) {
            ++bad;
            continue;
        }
        if (latest[board] == NULL) order[n_boards++] = (unsigned char)board;
        latest[board] = payload;
    }
    PyBuffer_Release(&board_of);
    PyObject *joined = PyBytes_FromStringAndSize(NULL, size * n_boards);
    if (joined == NULL) return NULL;
    char *out = PyBytes_AS_STRING(joined);
    for (int k = 0; k < n_boards; ++k) memcpy(out + k * size, PyBytes_AS_STRING(latest[order[k]]), (size_t)size);
    return Py_BuildValue("(y#Nll)", (const char *)order, (Py_ssize_t)n_boards, joined, unknown, bad);
}

/* encode_frames(receivers, sender, counters, payloads, size): one frame per receiver, as FrameEncoder.encode.
 *   receivers: bytes, one address per frame; payloads: n x ``size`` bytes, frame k's payload at k * size.
 *   counters: the encoder's 256 next-counter bytes (FrameCounter._next), advanced per receiver in place.
 *   Returns the frames (flag, escaped header + payload + FCS little-endian, flag) as a list of bytes. */
static PyObject *encode_frames(PyObject *module, PyObject *args) {
    Py_buffer receivers, counters, payloads;
    int sender;
    Py_ssize_t size;
    (void)module;
    if (!PyArg_ParseTuple(args, "y*iw*y*n", &receivers, &sender, &counters, &payloads, &size)) return NULL;
    PyObject *frames = NULL;
    if (counters.len != 256 || size < 0 || size > 255 || sender < 0 || sender > 255 ||
        payloads.len != receivers.len * size) {
        PyErr_SetString(PyExc_ValueError, "encode_frames: 256 counters, sender and size in 0..255, n x size payloads");
        goto done;
    }
    frames = PyList_New(receivers.len);
    if (frames == NULL) goto done;
    uint8_t *next = counters.buf;
    const uint8_t *to = receivers.buf, *data = payloads.buf;
    uint8_t raw[HEADER_SIZE + 255 + 2], wire[2 + 2 * (HEADER_SIZE + 255 + 2)];
    for (Py_ssize_t k = 0; k < receivers.len; ++k) {
        raw[0] = to[k];
        raw[1] = (uint8_t)sender;
        raw[2] = next[to[k]]++;
        raw[3] = (uint8_t)size;
        memcpy(raw + HEADER_SIZE, data + k * size, (size_t)size);
        Py_ssize_t body = HEADER_SIZE + size;
        uint16_t fcs = 0xFFFF;
        for (Py_ssize_t i = 0; i < body; ++i) fcs = (uint16_t)((fcs >> 8) ^ fcs_table[(fcs ^ raw[i]) & 0xFF]);
        raw[body] = (uint8_t)(fcs & 0xFF);
        raw[body + 1] = (uint8_t)(fcs >> 8);
        Py_ssize_t n = 0;
        wire[n++] = FLAG;
        for (Py_ssize_t i = 0; i < body + 2; ++i) {
            if (raw[i] == FLAG || raw[i] == ESCAPE) {
                wire[n++] = ESCAPE;
                wire[n++] = raw[i] ^ ESCAPE_XOR;
            } else {
                wire[n++] = raw[i];
            }
        }
        wire[n++] = FLAG;
        PyObject *frame = PyBytes_FromStringAndSize((const char *)wire, n);
        if (frame == NULL) {
            Py_CLEAR(frames);
            goto done;
        }
        PyList_SET_ITEM(frames, k, frame);
    }
done:
    PyBuffer_Release(&receivers);
    PyBuffer_Release(&counters);
    PyBuffer_Release(&payloads);
    return frames;
}

/* Little-endian reads of a TELEMETRY v1 record's fields (payloads.TELEMETRY_LAYOUT "<4B2HIQ4ihH", 40 bytes). */
#define TELEMETRY_SIZE 40
static uint16_t le16(const unsigned char *p) { return (uint16_t)(p[0] | p[1] << 8); }
static uint32_t le32(const unsigned char *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }
static uint64_t le64(const unsigned char *p) { return (uint64_t)le32(p) | (uint64_t)le32(p + 4) << 32; }

/* A writable buffer of exactly ``count`` items of ``itemsize`` bytes (float64 or int64 numpy arrays). */
static int check_items(Py_buffer *b, Py_ssize_t count, Py_ssize_t itemsize, const char *name) {
    if (b->len != count * itemsize) {
        PyErr_Format(PyExc_ValueError, "%s: %zd bytes, expected %zd", name, b->len, count * itemsize);
        return 0;
    }
    return 1;
}

/* decode_telemetry_into(payloads, boards, lsb, position, velocity, effort, temperature, status, errors, heard_ns,
 *                       heard_cycle, sent_ns, echoed, latencies, now_ns, cycle, temperature_lsb, max_mode)
 *   The driver's per-cycle telemetry work, as payloads.decode_telemetry_of followed by DriverCore's updates:
 *   payloads: k TELEMETRY v1 records (size, type and version already checked by newest_payloads);
 *   boards: their k board indices (bytes); lsb: 3 x n float64, the position, velocity and effort LSB per board.
 *   A record with mode > max_mode or a nonzero reserved field is invalid and skipped; for a valid one, at its
 *   board index: position, velocity, effort, temperature (float64, SI), status, errors (int64) are written and
 *   heard_ns / heard_cycle set to now_ns / cycle. sent_ns: 256 int64 send times by sequence % 256; echoed: n
 *   int64, the last sequence each board echoed. A valid record echoing a sequence that was sent and that its
 *   board had not echoed yet adds now_ns - sent to latencies (int64, room for k) and becomes the board's echoed
 *   one.
 *   Returns (invalid records, the valid records' largest board_time_us or -1, latencies written). */
static PyObject *decode_telemetry_into(PyObject *module, PyObject *args) {
    Py_buffer payloads, boards, lsb, out[6], heard_ns, heard_cycle, sent_ns, echoed, latencies;
    long long now_ns, cycle;
    double temperature_lsb;
    int max_mode;
    if (!PyArg_ParseTuple(args, "y*y*y*w*w*w*w*w*w*w*w*y*w*w*LLdi", &payloads, &boards, &lsb, &out[0], &out[1],
                          &out[2], &out[3], &out[4], &out[5], &heard_ns, &heard_cycle, &sent_ns, &echoed, &latencies,
                          &now_ns, &cycle, &temperature_lsb, &max_mode))
        return NULL;
    Py_buffer *all[] = {&payloads, &boards, &lsb, &out[0], &out[1], &out[2], &out[3], &out[4], &out[5],
                        &heard_ns, &heard_cycle, &sent_ns, &echoed, &latencies};
    PyObject *result = NULL;
    Py_ssize_t k = boards.len, n = heard_ns.len / 8;
    const char *names[] = {"position", "velocity", "effort", "temperature", "status", "errors"};
    int ok = payloads.len == k * TELEMETRY_SIZE && check_items(&lsb, 3 * n, 8, "lsb") &&
             check_items(&heard_cycle, n, 8, "heard_cycle") && check_items(&sent_ns, 256, 8, "sent_ns") &&
             check_items(&echoed, n, 8, "echoed") && latencies.len >= k * 8;
    for (int f = 0; ok && f < 6; ++f) ok = check_items(&out[f], n, 8, names[f]);
    if (!ok) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "one 40-byte record per board, and room for as many latencies");
        goto done;
    }
    const unsigned char *record = payloads.buf, *board_of = boards.buf;
    const double *scale = lsb.buf;
    double *position = out[0].buf, *velocity = out[1].buf, *effort = out[2].buf, *temperature = out[3].buf;
    int64_t *status = out[4].buf, *errors = out[5].buf, *heard = heard_ns.buf, *heard_at = heard_cycle.buf;
    const int64_t *sent = sent_ns.buf;
    int64_t *last_echo = echoed.buf, *latency = latencies.buf;
    long invalid = 0;
    long long board_time_max = -1;
    Py_ssize_t echoes = 0;
    for (Py_ssize_t i = 0; i < k; ++i, record += TELEMETRY_SIZE) {
        Py_ssize_t b = board_of[i];
        if (b >= n) {
            PyErr_Format(PyExc_ValueError, "board index %zd of %zd boards", b, n);
            goto done;
        }
        if (record[2] > max_mode || record[3] != 0 || le16(record + 38) != 0) {
            ++invalid;
            continue;
        }
        status[b] = le16(record + 4);
        errors[b] = le16(record + 6);
        position[b] = (int32_t)le32(record + 20) * scale[b];
        velocity[b] = (int32_t)le32(record + 24) * scale[n + b];
        effort[b] = (int32_t)le32(record + 28) * scale[2 * n + b];
        temperature[b] = (int16_t)le16(record + 36) * temperature_lsb;
        heard[b] = now_ns;
        heard_at[b] = cycle;
        long long board_time = (long long)le64(record + 12);
        if (board_time > board_time_max) board_time_max = board_time;
        int64_t sequence = le32(record + 8), sent_at = sent[sequence % 256];
        if (sent_at != 0 && sequence != last_echo[b]) {
            last_echo[b] = sequence;
            latency[echoes++] = now_ns - sent_at;
        }
    }
    result = Py_BuildValue("(lLn)", invalid, board_time_max, echoes);
done:
    for (size_t j = 0; j < sizeof(all) / sizeof(all[0]); ++j) PyBuffer_Release(all[j]);
    return result;
}

static PyMethodDef methods[] = {
    {"split_frames", split_frames, METH_VARARGS,
     "Decode every complete frame between flags; update the counters; return (frames, garbage, pending_offset)."},
    {"encode_frames", encode_frames, METH_VARARGS,
     "One frame per receiver from n x size payloads, advancing the counters: the frames as a list of bytes."},
    {"newest_payloads", newest_payloads, METH_VARARGS,
     "The latest payload of each board among frames: (boards, joined payloads, unknown senders, bad payloads)."},
    {"decode_telemetry_into", decode_telemetry_into, METH_VARARGS,
     "Decode newest_payloads' records into the driver's arrays: (invalid, largest board_time_us, latencies)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, .m_name = "_framing", .m_doc = "NDLCom deframing in C.", .m_size = -1, .m_methods = methods};

PyMODINIT_FUNC PyInit__framing(void) {
    make_fcs_table();
    return PyModule_Create(&module_def);
}
