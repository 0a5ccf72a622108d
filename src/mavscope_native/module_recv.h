/* The live receive part of mavscope._native (module_recv.c), added to the module by module.c. */
#ifndef MAVSCOPE_NATIVE_MODULE_RECV_H
#define MAVSCOPE_NATIVE_MODULE_RECV_H

#include <Python.h>

/* Add the Receiver type and UDP_PCAP_HEADER to the module: 0, or -1 with an exception set. */
int ms_py_add_receiver(PyObject *m);
/* udp_record(sec, nsec, src, sport, dst, dport, payload) -> bytes: one record as ms_udp_record makes it. */
PyObject *ms_py_udp_record(PyObject *mod, PyObject *args);

/* records_to_micro(records) -> (bytes, count): ms_records_to_micro. */
PyObject *ms_py_records_to_micro(PyObject *mod, PyObject *arg);

#endif
