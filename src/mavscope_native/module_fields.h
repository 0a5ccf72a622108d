/* `read -T fields`' line joiner (module_fields.c), added to the module by module.c. */
#ifndef MAVSCOPE_NATIVE_MODULE_FIELDS_H
#define MAVSCOPE_NATIVE_MODULE_FIELDS_H

#include <Python.h>

/* join_fields(columns, bounds, modes, separator, quote, aggregator) -> str: the -T fields lines (module_fields.c). */
PyObject *ms_py_join_fields(PyObject *mod, PyObject *args);

#endif
