"""Syntax trees: walked, copied and made (:func:`walk`, :func:`copy_tree`,
:func:`function_def`), and the rewrites of a function's statements made before it is
translated: the names it binds, how often, and loops over literal lists of ``params`` keys
written out one copy per key.
"""

from __future__ import annotations

import ast
from collections import deque


def walk(node):
    """Every node of the tree ``node``, in :func:`ast.walk`'s order, twice as fast (the
    translator and the writer walk each function's statements several times).

    Examples
    --------
    >>> [type(n).__name__ for n in walk(ast.parse("y = 2"))]
    ['Module', 'Assign', 'Name', 'Constant', 'Store']
    """
    todo = deque([node])
    take, add = todo.popleft, todo.append
    while todo:
        node = take()
        for name in node._fields:
            value = getattr(node, name, None)
            if isinstance(value, ast.AST):
                add(value)
            elif isinstance(value, list):
                for item in value:
                    if isinstance(item, ast.AST):
                        add(item)
        yield node


def copy_tree(node):
    """A copy of the syntax tree ``node`` (its nodes and lists new, its leaves shared).

    What :func:`copy.deepcopy` gives for a tree of :mod:`ast` nodes (whose leaves are
    strings, numbers and other constants), four times faster: the writer copies every
    function's statements at each new wiring.

    Examples
    --------
    >>> tree = ast.parse("y = 2 * x")
    >>> copied = copy_tree(tree)
    >>> copied is not tree, ast.dump(copied) == ast.dump(tree)
    (True, True)
    """
    if isinstance(node, list):
        return [copy_tree(item) for item in node]
    if not isinstance(node, ast.AST):
        return node
    cls = node.__class__
    new = cls.__new__(cls)
    fields = new.__dict__
    for name, value in node.__dict__.items():
        if isinstance(value, ast.AST | list):
            value = copy_tree(value)
        fields[name] = value
    return new


def function_def(name, arguments, body):
    """``def name(arguments): body`` as a syntax tree, its missing locations filled in.

    Examples
    --------
    >>> ast.unparse(function_def("double", ["x"], ast.parse("return 2 * x").body))
    'def double(x):\\n    return 2 * x'
    """
    args = ast.arguments(posonlyargs=[], args=[ast.arg(a) for a in arguments], vararg=None,
                         kwonlyargs=[], kw_defaults=[], kwarg=None, defaults=[])
    return ast.fix_missing_locations(ast.FunctionDef(
        name=name, args=args, body=body, decorator_list=[], returns=None, type_params=[]))


def _stored_names(body):
    """Names bound anywhere in ``body`` (assigned, loop targets, inner functions' args)."""
    names = set()
    for node in walk(ast.Module(body, [])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store | ast.Del):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.ExceptHandler) and node.name:
            names.add(node.name)
        elif isinstance(node, ast.alias):
            names.add((node.asname or node.name).split(".")[0])
    return names


def _store_counts(body):
    counts = {}
    for node in walk(ast.Module(body, [])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store | ast.Del):
            counts[node.id] = counts.get(node.id, 0) + 1
        elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name):
            counts[node.target.id] = counts.get(node.target.id, 0) + 1
    return counts


def _string_items(node, lookup):
    """The strings of a literal list/tuple of strings (or of a name holding one), else None.

    ``lookup(name)`` is ``(found, value)`` for a name read from outside the function.
    """
    if isinstance(node, ast.List | ast.Tuple):
        if node.elts and all(isinstance(e, ast.Constant) and isinstance(e.value, str)
                             for e in node.elts):
            return [e.value for e in node.elts]
        return None
    if isinstance(node, ast.Name):
        found, value = lookup(node.id)
        if found and isinstance(value, list | tuple) and value \
                and all(isinstance(v, str) for v in value):
            return list(value)
    return None


class _Substitute(ast.NodeTransformer):
    """Loads of ``name`` -> a constant."""

    def __init__(self, name, value):
        self.name, self.value = name, value

    def visit_Name(self, node):
        if node.id == self.name and isinstance(node.ctx, ast.Load):
            return ast.copy_location(ast.Constant(self.value), node)
        return node


class _Unroll(ast.NodeTransformer):
    """Loops and comprehensions over a literal sequence of strings (params keys), written
    out one copy per string, so that each key is a constant."""

    def __init__(self, lookup):
        self.lookup = lookup

    def visit_For(self, node):
        node = self.generic_visit(node)
        keys = _string_items(node.iter, self.lookup)
        if keys is None or not isinstance(node.target, ast.Name) or node.orelse or any(
                isinstance(n, ast.Break | ast.Continue) for n in walk(ast.Module(node.body, []))):
            return node
        out = []
        for key in keys:
            for stmt in copy_tree(node.body):
                out.append(_Substitute(node.target.id, key).visit(stmt))
        return out or [ast.Pass()]

    def _expand(self, node, make):
        if len(node.generators) != 1:
            return node
        gen = node.generators[0]
        keys = _string_items(gen.iter, self.lookup)
        if keys is None or gen.ifs or not isinstance(gen.target, ast.Name):
            return node
        items = [_Substitute(gen.target.id, k).visit(copy_tree(node.elt)) for k in keys]
        return ast.copy_location(make(items), node)

    def visit_ListComp(self, node):
        node = self.generic_visit(node)
        return self._expand(node, lambda items: ast.List(items, ast.Load()))

    def visit_GeneratorExp(self, node):
        node = self.generic_visit(node)
        return self._expand(node, lambda items: ast.Tuple(items, ast.Load()))
