"""CBBA's conflict resolution, Table 1 of Choi, Brunet & How (IEEE T-RO 25(4), 2009): one test
per row, each condition met and not met, written from the paper's table (not from
mrta_agent.cbba.table's code). Receiver i = 0, sender k = 1, third robots m = 2 and n = 3;
robot ids rank as their indices."""

from __future__ import annotations

import pytest

from mrta_agent.cbba.table import LEAVE, NONE, RESET, UPDATE, View, higher, resolve

I, K, M, N = 0, 1, 2, 3
RANK = [0, 1, 2, 3]
OLD, NEW = 1.0, 2.0


def act(sender, receiver, s_k=None, s_i=None):
    decision = resolve(I, K, View(*sender), View(*receiver), s_k or {}, s_i or {}, RANK)
    return decision.action, decision.row


def newer(robot):
    """Time stamps where the sender has later information from `robot` than the receiver."""
    return {robot: NEW}, {robot: OLD}


def older(robot):
    return {robot: OLD}, {robot: NEW}


# ------------------------------------------------------------------ the sender thinks it won
def test_row_1_sender_k_receiver_i_update_only_if_the_sender_bid_more():
    assert act((K, 0.7), (I, 0.5)) == (UPDATE, 1)
    assert act((K, 0.5), (I, 0.7)) == (LEAVE, 1)


def test_row_2_both_think_k_update():
    assert act((K, 0.3), (K, 0.9)) == (UPDATE, 2)


def test_row_3_sender_k_receiver_m_update_if_newer_about_m_or_higher_bid():
    assert act((K, 0.5), (M, 0.7), *newer(M)) == (UPDATE, 3)
    assert act((K, 0.7), (M, 0.5), *older(M)) == (UPDATE, 3)
    assert act((K, 0.5), (M, 0.7), *older(M)) == (LEAVE, 3)


def test_row_4_sender_k_receiver_none_update():
    assert act((K, 0.2), (NONE, 0.0)) == (UPDATE, 4)


# ------------------------------------------------------------------ the sender thinks i won
def test_row_5_both_think_i_leave():
    assert act((I, 0.4), (I, 0.4)) == (LEAVE, 5)


def test_row_6_sender_i_receiver_k_reset():
    assert act((I, 0.4), (K, 0.6)) == (RESET, 6)


def test_row_7_sender_i_receiver_m_reset_only_if_newer_about_m():
    assert act((I, 0.4), (M, 0.6), *newer(M)) == (RESET, 7)
    assert act((I, 0.4), (M, 0.6), *older(M)) == (LEAVE, 7)


def test_row_8_sender_i_receiver_none_leave():
    assert act((I, 0.4), (NONE, 0.0)) == (LEAVE, 8)


# ------------------------------------------------------------------ the sender thinks m won
def test_row_9_sender_m_receiver_i_update_only_if_newer_about_m_and_higher_bid():
    assert act((M, 0.7), (I, 0.5), *newer(M)) == (UPDATE, 9)
    assert act((M, 0.7), (I, 0.5), *older(M)) == (LEAVE, 9)
    assert act((M, 0.5), (I, 0.7), *newer(M)) == (LEAVE, 9)


def test_row_10_sender_m_receiver_k_update_if_newer_about_m_else_reset():
    assert act((M, 0.5), (K, 0.7), *newer(M)) == (UPDATE, 10)
    assert act((M, 0.5), (K, 0.7), *older(M)) == (RESET, 10)


def test_row_11_both_think_m_update_only_if_newer_about_m():
    assert act((M, 0.5), (M, 0.7), *newer(M)) == (UPDATE, 11)
    assert act((M, 0.5), (M, 0.7), *older(M)) == (LEAVE, 11)


def test_row_12_sender_m_receiver_n():
    both_newer = ({M: NEW, N: NEW}, {M: OLD, N: OLD})
    m_newer = ({M: NEW, N: OLD}, {M: OLD, N: NEW})
    n_newer_m_older = ({M: OLD, N: NEW}, {M: NEW, N: OLD})
    n_newer_m_same = ({M: OLD, N: NEW}, {M: OLD, N: OLD})
    assert act((M, 0.1), (N, 0.9), *both_newer) == (UPDATE, 12)  # newer about m and n
    assert act((M, 0.9), (N, 0.1), *m_newer) == (UPDATE, 12)     # newer about m, higher bid
    assert act((M, 0.1), (N, 0.9), *m_newer) == (LEAVE, 12)      # newer about m, lower bid
    assert act((M, 0.9), (N, 0.1), *n_newer_m_older) == (RESET, 12)
    assert act((M, 0.9), (N, 0.1), *n_newer_m_same) == (LEAVE, 12)  # s_im > s_km is strict
    assert act((M, 0.9), (N, 0.1), *older(M)) == (LEAVE, 12)


def test_row_13_sender_m_receiver_none_update_only_if_newer_about_m():
    assert act((M, 0.5), (NONE, 0.0), *newer(M)) == (UPDATE, 13)
    assert act((M, 0.5), (NONE, 0.0), *older(M)) == (LEAVE, 13)


# ------------------------------------------------------------------ the sender knows no winner
def test_row_14_sender_none_receiver_i_leave():
    assert act((NONE, 0.0), (I, 0.5)) == (LEAVE, 14)


def test_row_15_sender_none_receiver_k_update():
    assert act((NONE, 0.0), (K, 0.5)) == (UPDATE, 15)


def test_row_16_sender_none_receiver_m_update_only_if_newer_about_m():
    assert act((NONE, 0.0), (M, 0.5), *newer(M)) == (UPDATE, 16)
    assert act((NONE, 0.0), (M, 0.5), *older(M)) == (LEAVE, 16)


def test_row_17_neither_knows_a_winner_leave():
    assert act((NONE, 0.0), (NONE, 0.0)) == (LEAVE, 17)


# ------------------------------------------------------------------ what "higher" and "newer" mean
def test_an_equal_bid_is_higher_when_its_winner_has_the_lower_id():
    assert act((K, 0.5), (I, 0.5)) == (LEAVE, 1)  # i (rank 0) keeps it
    rank = [1, 0]  # now k has the lower id
    assert resolve(I, K, View(K, 0.5), View(I, 0.5), {}, {}, rank).action == UPDATE
    assert higher(View(M, 0.5), View(N, 0.5), RANK) and not higher(View(N, 0.5), View(M, 0.5), RANK)
    assert higher(View(M, 0.1), View(NONE, 0.0), RANK)


@pytest.mark.parametrize("s_k, s_i, expected", [({}, {}, LEAVE), ({M: 0.0}, {}, UPDATE),
                                                ({}, {M: 0.0}, LEAVE)])
def test_a_robot_never_heard_from_has_no_time_stamp(s_k, s_i, expected):
    assert resolve(I, K, View(M, 0.5), View(NONE, 0.0), s_k, s_i, RANK).action == expected
